# CAN motion stack (issue 6): bus -> CANopen (CiA 301 subset) -> CiA 402 drive,
# simulated drive, tools and tests. ROS-free: linux/can.h + yaml-cpp only.
# Included from the top-level CMakeLists.txt after the core libraries.

add_library(massage_cell_can STATIC
  src/can/bus.cpp
  src/can/virtual_bus.cpp
  src/can/socketcan_bus.cpp
  src/can/canopen.cpp
  src/can/config.cpp
  src/can/sdo_client.cpp
  src/can/master.cpp
  src/can/cia402.cpp
  src/can/object_dictionary.cpp
  src/can/sim_drive.cpp
  src/can/probe.cpp
  src/can/realtime.cpp)
target_include_directories(massage_cell_can PUBLIC include)
target_link_libraries(massage_cell_can PUBLIC yaml-cpp Threads::Threads)

# Command-line tools: simulated drives on a SocketCAN interface, bus scan,
# timing bench on the virtual bus.
foreach(tool can_sim_drive can_probe can_bench)
  add_executable(${tool} src/tools/${tool}.cpp)
  target_link_libraries(${tool} massage_cell_can)
endforeach()
target_compile_definitions(can_bench PRIVATE MASSAGE_CELL_SOURCE_DIR="${PROJECT_SOURCE_DIR}")
install(TARGETS can_sim_drive can_probe can_bench
  RUNTIME DESTINATION ${CATKIN_PACKAGE_BIN_DESTINATION})

if(CATKIN_ENABLE_TESTING)
  foreach(name bus canopen config master cia402 sim_drive drive probe)
    catkin_add_gtest(test_can_${name} ${PROJECT_SOURCE_DIR}/test/can/test_${name}.cpp)
    if(TARGET test_can_${name})
      target_link_libraries(test_can_${name} massage_cell_can)
      target_compile_definitions(test_can_${name} PRIVATE MASSAGE_CELL_SOURCE_DIR="${PROJECT_SOURCE_DIR}")
    endif()
  endforeach()
  catkin_add_gtest(test_can_tools ${PROJECT_SOURCE_DIR}/test/can/test_tools.cpp)
  if(TARGET test_can_tools)
    target_compile_definitions(test_can_tools PRIVATE
      MASSAGE_CELL_SOURCE_DIR="${PROJECT_SOURCE_DIR}"
      CAN_PROBE_TOOL="$<TARGET_FILE:can_probe>"
      CAN_SIM_DRIVE_TOOL="$<TARGET_FILE:can_sim_drive>"
      CAN_BENCH_TOOL="$<TARGET_FILE:can_bench>")
    add_dependencies(test_can_tools can_probe can_sim_drive can_bench)
  endif()
endif()
