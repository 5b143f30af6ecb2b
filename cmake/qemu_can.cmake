# Real-Linux-kernel SocketCAN test (issue 6): Debian's own kernel booted under
# qemu (TCG software emulation: these machines have no CAN in their kernel and
# no KVM) loads can / can-raw / can-dev / vcan, creates vcan0 and runs the
# statically linked can_kernel_smoke checks against it. See
# scripts/qemu_can/run.sh (harness) and scripts/qemu_can/prepare.sh (fetches the
# kernel of the linux-image-amd64 metapackage once with `apt-get download`,
# then works offline from ${CMAKE_BINARY_DIR}/qemu_can).
#
# Included from test/CMakeLists.txt (testing enabled). Needs the Debian packages
# qemu-system-x86 busybox-static cpio (scripts/setup.sh installs them): when
# qemu is missing or the kernel cannot be fetched the test fails, saying why.

# The guest has no libraries: link statically (glibc's libc.a, libstdc++.a).
add_executable(can_kernel_smoke ${PROJECT_SOURCE_DIR}/src/tools/can_kernel_smoke.cpp)
set_target_properties(can_kernel_smoke PROPERTIES POSITION_INDEPENDENT_CODE OFF)
target_link_options(can_kernel_smoke PRIVATE -static)
if(TARGET tests)
  add_dependencies(tests can_kernel_smoke)
endif()

set(QEMU_CAN_CACHE ${CMAKE_BINARY_DIR}/qemu_can CACHE PATH
    "Where scripts/qemu_can/prepare.sh keeps Debian's kernel and CAN modules")

# A responder process in the background (like a simulated drive) and the
# checking process in the foreground, both on the guest's vcan0.
add_test(NAME qemu_can_kernel_smoke
  COMMAND ${PROJECT_SOURCE_DIR}/scripts/qemu_can/run.sh
          --prepare --cache ${QEMU_CAN_CACHE} --timeout 120
          --expect "^CAN_KERNEL_SMOKE OK$"
          -- $<TARGET_FILE:can_kernel_smoke> --serve
          ::: $<TARGET_FILE:can_kernel_smoke> --frames 1000 --peer 200)
set_tests_properties(qemu_can_kernel_smoke PROPERTIES
  TIMEOUT 170
  PROCESSORS 2
  LABELS "qemu;can"
  PASS_REGULAR_EXPRESSION "\\[qemu_can/run\\] PASS: guest exit code 0"
  FAIL_REGULAR_EXPRESSION "qemu_can/run.sh: ERROR;CAN_KERNEL_SMOKE FAIL")
