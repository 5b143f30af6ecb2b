# Three-axis massage arm (issue 7): the ROS-free controller library on the
# CAN stack (Eigen + yaml-cpp + massage_cell_can), the arm_bench tool, and
# their tests. Included from the top-level CMakeLists.txt after can.cmake.

add_library(massage_cell_arm STATIC
  src/arm/config.cpp
  src/arm/profile.cpp
  src/arm/plan.cpp
  src/arm/controller.cpp
  src/arm/sim_cell.cpp
  src/arm/session.cpp)
target_include_directories(massage_cell_arm PUBLIC include ${EIGEN3_INCLUDE_DIR} ${OpenCV_INCLUDE_DIRS})
target_link_libraries(massage_cell_arm PUBLIC massage_cell_can yaml-cpp ${OpenCV_LIBS} Threads::Threads)

# Cycle jitter, e-stop latency and move error against the simulated drives.
add_executable(arm_bench src/tools/arm_bench.cpp)
target_link_libraries(arm_bench massage_cell_arm)
target_compile_definitions(arm_bench PRIVATE MASSAGE_CELL_SOURCE_DIR="${PROJECT_SOURCE_DIR}")
install(TARGETS massage_cell_arm ARCHIVE DESTINATION ${CATKIN_PACKAGE_LIB_DESTINATION})
install(TARGETS arm_bench RUNTIME DESTINATION ${CATKIN_PACKAGE_BIN_DESTINATION})

if(CATKIN_ENABLE_TESTING)
  foreach(name config profile plan controller session)
    catkin_add_gtest(test_arm_${name} ${PROJECT_SOURCE_DIR}/test/arm/test_${name}.cpp)
    if(TARGET test_arm_${name})
      target_link_libraries(test_arm_${name} massage_cell_arm)
      target_compile_definitions(test_arm_${name} PRIVATE MASSAGE_CELL_SOURCE_DIR="${PROJECT_SOURCE_DIR}")
    endif()
  endforeach()
  catkin_add_gtest(test_arm_bench_tool ${PROJECT_SOURCE_DIR}/test/arm/test_bench_tool.cpp)
  if(TARGET test_arm_bench_tool)
    target_compile_definitions(test_arm_bench_tool PRIVATE
      MASSAGE_CELL_SOURCE_DIR="${PROJECT_SOURCE_DIR}"
      ARM_BENCH_TOOL="$<TARGET_FILE:arm_bench>")
    add_dependencies(test_arm_bench_tool arm_bench)
  endif()
endif()

# ---------------------------------------------------------------------------
# ROS wrapper: the arm nodelet (its own plugin library, see nodelet_plugins.xml)
# and node; the plain URDF of the cell (urdf/massage_arm.urdf) for
# robot_state_publisher; rostests with simulated drives.
add_library(massage_cell_arm_nodelet src/nodes/arm_nodelet.cpp)
target_include_directories(massage_cell_arm_nodelet PRIVATE include ${CATKIN_DEVEL_PREFIX}/include ${catkin_INCLUDE_DIRS})
target_link_libraries(massage_cell_arm_nodelet massage_cell_arm ${catkin_LIBRARIES} yaml-cpp)
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

if(CATKIN_ENABLE_TESTING)
  # The URDF parses (urdfdom's check_urdf, Debian's liburdfdom-tools).
  add_test(NAME arm_check_urdf COMMAND check_urdf ${PROJECT_SOURCE_DIR}/urdf/massage_arm.urdf)
  # The node with simulated drives, robot_state_publisher and a test node
  # publishing acupoint frames.
  find_package(rostest REQUIRED)
  find_package(urdf REQUIRED)
  add_rostest_gtest(test_arm_node ${PROJECT_SOURCE_DIR}/test/ros/arm.test ${PROJECT_SOURCE_DIR}/test/ros/test_arm_node.cpp)
  if(TARGET test_arm_node)
    target_include_directories(test_arm_node PRIVATE include ${CATKIN_DEVEL_PREFIX}/include ${catkin_INCLUDE_DIRS} ${urdf_INCLUDE_DIRS})
    target_link_libraries(test_arm_node massage_cell_arm ${catkin_LIBRARIES} ${urdf_LIBRARIES})
    target_compile_definitions(test_arm_node PRIVATE MASSAGE_CELL_SOURCE_DIR="${PROJECT_SOURCE_DIR}")
    add_dependencies(test_arm_node arm_node massage_cell_arm_nodelet ${PROJECT_NAME}_generate_messages_cpp)
  endif()
  # The same test node against can_interface can9 (no such interface): one
  # error, the node keeps running, every command refused with the reason.
  add_rostest(${PROJECT_SOURCE_DIR}/test/ros/arm_bad_interface.test DEPENDENCIES test_arm_node)
  # cell.launch with the arm on: one parent and one publisher per tf frame.
  add_rostest_gtest(test_arm_cell_tf ${PROJECT_SOURCE_DIR}/test/ros/arm_cell_tf.test
                    ${PROJECT_SOURCE_DIR}/test/ros/test_arm_cell_tf.cpp)
  if(TARGET test_arm_cell_tf)
    target_include_directories(test_arm_cell_tf PRIVATE ${catkin_INCLUDE_DIRS})
    target_link_libraries(test_arm_cell_tf ${catkin_LIBRARIES})
    add_dependencies(test_arm_cell_tf arm_node massage_cell_arm_nodelet)
  endif()
endif()
