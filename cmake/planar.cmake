# Piecewise-planar reconstruction from multiple calibrated views (issue 27,
# thesis Ch. 4 after Baillard & Zisserman): the ROS-free library, its tools
# and its tests. Included from the top-level CMakeLists.txt.

add_library(massage_cell_planar STATIC
  src/planar/views.cpp
  src/planar/camera_views.cpp
  src/planar/features.cpp
  src/planar/model.cpp
  src/planar/coplanarity.cpp
  src/planar/photo_consistency.cpp
  src/planar/half_plane.cpp
  src/planar/extend.cpp
  src/planar/delineate.cpp
  src/planar/reconstruct.cpp
  src/planar/evaluation.cpp)
target_include_directories(massage_cell_planar PUBLIC include ${OpenCV_INCLUDE_DIRS} ${EIGEN3_INCLUDE_DIR})
target_link_libraries(massage_cell_planar PUBLIC massage_cell_camera ${OpenCV_LIBS} yaml-cpp Threads::Threads)
install(TARGETS massage_cell_planar ARCHIVE DESTINATION ${CATKIN_PACKAGE_LIB_DESTINATION})

# Command-line tools: views in, planes out; the evaluation against exact planes.
add_executable(planar_reconstruct src/tools/planar_reconstruct.cpp)
target_link_libraries(planar_reconstruct massage_cell_planar)
add_executable(planar_eval src/tools/planar_eval.cpp)
target_link_libraries(planar_eval massage_cell_planar massage_cell_sim)
massage_cell_tool_paths(planar_eval)
install(TARGETS planar_reconstruct planar_eval RUNTIME DESTINATION ${CATKIN_PACKAGE_BIN_DESTINATION})
