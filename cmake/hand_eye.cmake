# Hand-eye calibration of the stereo camera against the gantry: the ROS-free
# library (ChArUco marker detection with OpenCV's contrib aruco module,
# triangulation, umeyama fit, YAML), its simulator scene, the
# hand_eye_calibrate tool and the gtest. Included from the top-level
# CMakeLists.txt after planar.cmake.

# aruco is in Debian 12's libopencv-contrib-dev (already in scripts/debian_packages.txt).
# Checked inside a function so that OpenCV_LIBS of the including scope stays
# as CMakeLists.txt set it; opencv_aruco is an imported target of OpenCV's config.
function(massage_cell_require_aruco)
  find_package(OpenCV REQUIRED COMPONENTS aruco)
endfunction()
massage_cell_require_aruco()

add_library(massage_cell_calib STATIC
  src/calib/hand_eye.cpp
  src/calib/hand_eye_io.cpp
  src/calib/stereo_marker.cpp
  src/calib/recorded_set.cpp)
target_include_directories(massage_cell_calib PUBLIC include ${OpenCV_INCLUDE_DIRS} ${EIGEN3_INCLUDE_DIR})
target_link_libraries(massage_cell_calib PUBLIC massage_cell_camera opencv_aruco ${OpenCV_LIBS} yaml-cpp)

# The simulated calibration cell (marker geometry, poses, rendering).
add_library(massage_cell_calib_sim STATIC src/sim/hand_eye_scene.cpp)
target_link_libraries(massage_cell_calib_sim PUBLIC massage_cell_calib massage_cell_sim)
install(TARGETS massage_cell_calib massage_cell_calib_sim ARCHIVE DESTINATION ${CATKIN_PACKAGE_LIB_DESTINATION})

add_executable(hand_eye_calibrate src/tools/hand_eye_calibrate.cpp)
target_link_libraries(hand_eye_calibrate massage_cell_calib_sim massage_cell_arm)
massage_cell_tool_paths(hand_eye_calibrate)
install(TARGETS hand_eye_calibrate RUNTIME DESTINATION ${CATKIN_PACKAGE_BIN_DESTINATION})
