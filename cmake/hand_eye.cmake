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

if(CATKIN_ENABLE_TESTING)
  catkin_add_gtest(test_hand_eye ${PROJECT_SOURCE_DIR}/test/calib/test_hand_eye.cpp)
  if(TARGET test_hand_eye)
    target_link_libraries(test_hand_eye massage_cell_calib_sim)
    target_compile_definitions(test_hand_eye PRIVATE MASSAGE_CELL_SOURCE_DIR="${PROJECT_SOURCE_DIR}")
  endif()
  # scripts/calibrated_urdf.py: the URDF's camera mount from a calibration (arm.launch camera_calibration:=FILE).
  add_test(NAME calibrated_urdf COMMAND /usr/bin/python3 ${PROJECT_SOURCE_DIR}/test/calib/test_calibrated_urdf.py)
endif()

add_executable(hand_eye_calibrate src/tools/hand_eye_calibrate.cpp)
target_link_libraries(hand_eye_calibrate massage_cell_calib_sim massage_cell_arm)
target_compile_definitions(hand_eye_calibrate PRIVATE MASSAGE_CELL_SOURCE_DIR="${PROJECT_SOURCE_DIR}")
install(TARGETS hand_eye_calibrate RUNTIME DESTINATION ${CATKIN_PACKAGE_BIN_DESTINATION})
