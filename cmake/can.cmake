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
  src/can/sim_drive_comm.cpp
  src/can/sim_drive_sdo.cpp
  src/can/sim_drive_motion.cpp
  src/can/sim_mechanics.cpp
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
# can_sim_drive --body: arm::SimBody (massage_cell_arm, defined in arm.cmake) as the Z drive's external force.
target_link_libraries(can_sim_drive massage_cell_arm)
massage_cell_tool_paths(can_bench)
install(TARGETS can_sim_drive can_probe can_bench
  RUNTIME DESTINATION ${CATKIN_PACKAGE_BIN_DESTINATION})
