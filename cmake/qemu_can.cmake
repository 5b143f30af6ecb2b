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

# System test of the whole CAN motion stack on the guest's vcan0 (issue 6):
# can_sim_drive (the three simulated CiA 402 drives of config/can_axes.yaml,
# with its opt-in fault test hook on id 0x6C0) in the background, the CANopen
# master can_kernel_system in the foreground: bring-up, enable, homing, moves,
# an injected drive fault with fault reset, error-passive and two bus-offs
# injected as kernel error frames (CAN_ERR_FLAG, written by a second socket)
# while the axes move (report, back-off reopen 100 then 200 ms, moves finish),
# and the interface going down and up again. See src/tools/can_kernel_system.cpp.
# Plus the timing bench on vcan0 (qemu_can_bench, below).
# Static copies for the guest; massage_cell_can itself is an ordinary (PIC)
# static library, which links into a static executable just as well. Debian's
# libyaml-cpp-dev ships libyaml-cpp.a: link it explicitly (the yaml-cpp target
# of the library's interface names the shared one).
find_library(QEMU_CAN_YAML_CPP_STATIC NAMES libyaml-cpp.a)
if(QEMU_CAN_YAML_CPP_STATIC)
  set(_qemu_can_yaml ${QEMU_CAN_YAML_CPP_STATIC})
else()
  message(WARNING "libyaml-cpp.a not found (Debian: libyaml-cpp-dev): the static qemu_can_system programs will not link")
  set(_qemu_can_yaml yaml-cpp)
endif()
add_executable(can_kernel_system ${PROJECT_SOURCE_DIR}/src/tools/can_kernel_system.cpp)
add_executable(can_sim_drive_static ${PROJECT_SOURCE_DIR}/src/tools/can_sim_drive.cpp)
add_executable(can_bench_static ${PROJECT_SOURCE_DIR}/src/tools/can_bench.cpp)
add_executable(can_kernel_force ${PROJECT_SOURCE_DIR}/src/tools/can_kernel_force.cpp)
foreach(t can_kernel_system can_sim_drive_static can_bench_static can_kernel_force)
  set_target_properties(${t} PROPERTIES POSITION_INDEPENDENT_CODE OFF)
  # can_sim_drive (--body: arm::SimBody) and can_kernel_force (arm::Controller)
  # need massage_cell_arm too; the others do not use it.
  set(_qemu_can_libs $<TARGET_FILE:massage_cell_can>)
  if(t STREQUAL "can_sim_drive_static" OR t STREQUAL "can_kernel_force")
    target_include_directories(${t} PRIVATE $<TARGET_PROPERTY:massage_cell_arm,INTERFACE_INCLUDE_DIRECTORIES>)
    set(_qemu_can_libs $<TARGET_FILE:massage_cell_arm> $<TARGET_FILE:massage_cell_can>)
    add_dependencies(${t} massage_cell_arm)
  endif()
  target_include_directories(${t} PRIVATE $<TARGET_PROPERTY:massage_cell_can,INTERFACE_INCLUDE_DIRECTORIES>)
  # The libraries' objects, then the static yaml-cpp and threads: not their
  # PUBLIC yaml-cpp target (that would pull libyaml-cpp.so into -static).
  target_link_libraries(${t} ${_qemu_can_libs} ${_qemu_can_yaml} Threads::Threads)
  add_dependencies(${t} massage_cell_can)
  target_link_options(${t} PRIVATE -static)
  if(TARGET tests)
    add_dependencies(tests ${t})
  endif()
endforeach()

add_test(NAME qemu_can_system
  COMMAND ${PROJECT_SOURCE_DIR}/scripts/qemu_can/run.sh
          --prepare --cache ${QEMU_CAN_CACHE} --timeout 150
          --file ${PROJECT_SOURCE_DIR}/config/can_axes.yaml
          --expect "^CAN_KERNEL_SYSTEM OK$"
          -- $<TARGET_FILE:can_sim_drive_static> --interface vcan0 --config /data/can_axes.yaml --fault-frame-id 0x6C0
          ::: $<TARGET_FILE:can_kernel_system> /data/can_axes.yaml --interface vcan0 --fault-frame-id 0x6C0)
set_tests_properties(qemu_can_system PROPERTIES
  TIMEOUT 170
  PROCESSORS 2
  LABELS "qemu;can"
  PASS_REGULAR_EXPRESSION "\\[qemu_can/run\\] PASS: guest exit code 0"
  FAIL_REGULAR_EXPRESSION "qemu_can/run.sh: ERROR;CAN_KERNEL_SYSTEM FAIL")

# Force control end to end on the guest's vcan0 (issue 45): can_sim_drive with
# --body 0.15 (a flat breathing back under the Z drive, its skin 0.15 m up in
# the Z drive's physical frame = tool z 0.15 with config/arm.yaml's zero
# tool_offset) in the background, can_kernel_force in the foreground: an
# arm::Controller on a SocketCanBus homes (force calibration at its end), then
# presses by force (30 N, lower_back, 2 s hold) over the body and checks the
# press ends, the estimate held 30 N and the tool sat plausibly below the skin.
# See src/tools/can_kernel_force.cpp. arm.yaml finds can_axes.yaml and
# acupoints.yaml next to it (/data). One guest CPU (--smp 1), as qemu_can_bench:
# with two, TCG's cross-vCPU wake-ups put the 10 ms cycle's jitter p99 at
# 2.9-3.5 ms (1.0-3.0 ms with one) and once skewed the homing's force calibration
# enough for a false contact in the seek (1 run of 4).
# The guest's clock counts its instructions (--icount shift=3,sleep=off: 8 ns
# each, a 125 MIPS CPU; idle time skipped): on the host's clock a host loaded by
# other tests starved the emulated CPU into 60-126 ms gaps in the 10 ms cycle
# (out of the controller's spec: false contacts in the air, an invalid estimate
# after homing). With icount the cycle holds its period whatever the host does
# (jitter p99 0.17-0.19 ms, max 0.4-0.7 ms, also beside 3 CPU hogs); a loaded host
# only stretches the wall time (31-41 s alone, 60-128 s beside 3 hogs + a test):
# hence the longer timeouts.
add_test(NAME qemu_can_force
  COMMAND ${PROJECT_SOURCE_DIR}/scripts/qemu_can/run.sh
          --prepare --cache ${QEMU_CAN_CACHE} --timeout 240 --smp 1 --icount shift=3,sleep=off
          --file ${PROJECT_SOURCE_DIR}/config/arm.yaml
          --file ${PROJECT_SOURCE_DIR}/config/can_axes.yaml
          --file ${PROJECT_SOURCE_DIR}/config/acupoints.yaml
          --expect "^CAN_KERNEL_FORCE OK"
          -- $<TARGET_FILE:can_sim_drive_static> --interface vcan0 --config /data/can_axes.yaml --body 0.15 --status-s 1
          ::: $<TARGET_FILE:can_kernel_force> /data/arm.yaml --interface vcan0 --skin-z 0.15 --max-late-cycles 0)
set_tests_properties(qemu_can_force PROPERTIES
  TIMEOUT 260
  PROCESSORS 2
  LABELS "qemu;can;arm"
  PASS_REGULAR_EXPRESSION "\\[qemu_can/run\\] PASS: guest exit code 0"
  FAIL_REGULAR_EXPRESSION "qemu_can/run.sh: ERROR;CAN_KERNEL_FORCE FAIL")

# SDO round trip and PDO cycle timing over the guest kernel's SocketCAN (issue
# 6): can_bench --interface vcan0, master, simulated drive and sniffer on their
# own CAN_RAW sockets in one process (the drive's fault is injected in-process
# at a known instant). One guest CPU (--smp 1): TCG wake-ups across vCPUs add
# milliseconds of jitter that would measure qemu, not the stack (see
# scripts/qemu_can/README.md). Generous timeouts for the emulated CPU; the test
# passes on the bench's own success line, which needs every sample and the p99
# limits.
add_test(NAME qemu_can_bench
  COMMAND ${PROJECT_SOURCE_DIR}/scripts/qemu_can/run.sh
          --prepare --cache ${QEMU_CAN_CACHE} --timeout 120 --smp 1
          --file ${PROJECT_SOURCE_DIR}/config/can_axes.yaml
          --expect "^CAN_BENCH OK$"
          -- $<TARGET_FILE:can_bench_static> --interface vcan0 --config /data/can_axes.yaml
             --samples 1000 --faults 20 --sdo-timeout-ms 500 --heartbeat-timeout-ms 1000 --max-p99-ms 50)
set_tests_properties(qemu_can_bench PROPERTIES
  TIMEOUT 170
  PROCESSORS 2
  LABELS "qemu;can"
  PASS_REGULAR_EXPRESSION "\\[qemu_can/run\\] PASS: guest exit code 0"
  FAIL_REGULAR_EXPRESSION "qemu_can/run.sh: ERROR;CAN_BENCH FAIL")
