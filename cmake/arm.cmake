# Three-axis massage arm (issue 7): the ROS-free controller library on the
# CAN stack (Eigen + yaml-cpp + massage_cell_can), the arm_bench tool, and
# their tests. Included from the top-level CMakeLists.txt after can.cmake.

add_library(massage_cell_arm STATIC
  src/arm/config.cpp
  src/arm/node_options.cpp
  src/arm/profile.cpp
  src/arm/plan.cpp
  src/arm/controller.cpp
  src/arm/controller_force.cpp
  src/arm/sim_cell.cpp
  src/arm/sim_body.cpp
  src/arm/force_estimate.cpp
  src/arm/tool_force.cpp
  src/arm/force_press.cpp
  src/arm/session.cpp)
target_include_directories(massage_cell_arm PUBLIC include ${EIGEN3_INCLUDE_DIR})
target_link_libraries(massage_cell_arm PUBLIC massage_cell_can yaml-cpp Threads::Threads)

# Cycle jitter, e-stop latency and move error against the simulated drives.
add_executable(arm_bench src/tools/arm_bench.cpp src/tools/arm_bench_force.cpp)
target_link_libraries(arm_bench massage_cell_arm)
massage_cell_tool_paths(arm_bench)
install(TARGETS massage_cell_arm ARCHIVE DESTINATION ${CATKIN_PACKAGE_LIB_DESTINATION})
install(TARGETS arm_bench RUNTIME DESTINATION ${CATKIN_PACKAGE_BIN_DESTINATION})

# ---------------------------------------------------------------------------
# ROS wrapper: the arm nodelet (its own plugin library, see nodelet_plugins.xml)
# and node; the plain URDF of the cell (urdf/massage_arm.urdf) for
# robot_state_publisher; rostests with simulated drives.
add_library(massage_cell_arm_nodelet src/nodes/arm_nodelet.cpp src/nodes/arm_interface.cpp src/nodes/arm_action.cpp)
target_include_directories(massage_cell_arm_nodelet PRIVATE include ${CATKIN_DEVEL_PREFIX}/include ${catkin_INCLUDE_DIRS})
target_link_libraries(massage_cell_arm_nodelet massage_cell_arm massage_cell_node_tf ${catkin_LIBRARIES})
add_dependencies(massage_cell_arm_nodelet ${PROJECT_NAME}_generate_messages_cpp)
add_executable(arm_node src/nodes/arm_node.cpp)
target_include_directories(arm_node PRIVATE ${catkin_INCLUDE_DIRS})
target_link_libraries(arm_node ${catkin_LIBRARIES})
add_dependencies(arm_node massage_cell_arm_nodelet)
install(TARGETS massage_cell_arm_nodelet
  ARCHIVE DESTINATION ${CATKIN_PACKAGE_LIB_DESTINATION}
  LIBRARY DESTINATION ${CATKIN_PACKAGE_LIB_DESTINATION})
install(TARGETS arm_node RUNTIME DESTINATION ${CATKIN_PACKAGE_BIN_DESTINATION})
install(DIRECTORY urdf DESTINATION ${CATKIN_PACKAGE_SHARE_DESTINATION})
