# rviz/cell.rviz: the cell in rviz (cell.launch rviz:=true), and its test.
#
# test/ros/rviz_cell.test replays the bundled bag into hbds, cect, planar and the arm
# (robot_state_publisher) and renders rviz/cell.rviz under Xvfb (test/ros/test_rviz_cell.cpp:
# screenshots with and without the RobotModel / PointCloud2 displays, compared in the 3D
# view; the pictures go to test_results/massage_cell/rviz_cell/). Needs xvfb, imagemagick
# (import), libgl1-mesa-dri and rviz. Without Xvfb the ctest is reported Skipped with the
# reason: it runs through test/ros/rviz_cell.sh, which checks for Xvfb before rostest
# (a skipped gtest inside rostest would show as a pass), so it is registered by hand here
# the way add_rostest_gtest registers the others (same target names and result files).
install(DIRECTORY rviz DESTINATION ${CATKIN_PACKAGE_SHARE_DESTINATION})

if(CATKIN_ENABLE_TESTING)
  find_package(rostest REQUIRED)
  if(GTEST_FOUND)
    add_executable(test_rviz_cell EXCLUDE_FROM_ALL ${PROJECT_SOURCE_DIR}/test/ros/test_rviz_cell.cpp)
    target_include_directories(test_rviz_cell PRIVATE ${GTEST_INCLUDE_DIRS} ${catkin_INCLUDE_DIRS})
    target_link_libraries(test_rviz_cell ${GTEST_LIBRARIES} ${catkin_LIBRARIES} ${OpenCV_LIBS} yaml-cpp)
    if(TARGET tests)
      add_dependencies(tests test_rviz_cell)
    endif()
    # The nodes the launch file runs (roslaunch takes them from devel/).
    add_dependencies(test_rviz_cell hbds_node cect_node planar_node arm_node
                     massage_cell_nodelets massage_cell_arm_nodelet)

    find_program(MASSAGE_CELL_ROSTEST rostest PATHS /usr/bin)
    set(_rviz_xml rostest-test_ros_rviz_cell.xml)
    catkin_run_tests_target("rostest" "test_ros_rviz_cell.test" "${_rviz_xml}"
      COMMAND "bash ${PROJECT_SOURCE_DIR}/test/ros/rviz_cell.sh ${CATKIN_TEST_RESULTS_DIR}/${PROJECT_NAME}/${_rviz_xml} ${PYTHON_EXECUTABLE} ${MASSAGE_CELL_ROSTEST} --pkgdir=${PROJECT_SOURCE_DIR} --package=${PROJECT_NAME} --results-filename test_ros_rviz_cell.xml --results-base-dir \"${CATKIN_TEST_RESULTS_DIR}\" ${PROJECT_SOURCE_DIR}/test/ros/rviz_cell.test"
      DEPENDENCIES test_rviz_cell)
    set_tests_properties(_ctest_${PROJECT_NAME}_rostest_test_ros_rviz_cell.test PROPERTIES
                         SKIP_REGULAR_EXPRESSION "rviz_cell SKIPPED" TIMEOUT 180)
  endif()
endif()
