# The massage session's report (issue 45): the ROS-free library of its
# records, summary, index.html and pictures (OpenCV + Eigen), which the
# massage_session node fills. The routine and the stable-fix test stay in the
# arm library (arm/session.h). Included from the top-level CMakeLists.txt
# after arm.cmake.

add_library(massage_cell_session_report STATIC
  src/session/report.cpp
  src/session/report_html.cpp
  src/session/report_draw.cpp
  src/session/force_plot.cpp)
target_include_directories(massage_cell_session_report PUBLIC include ${EIGEN3_INCLUDE_DIR} ${OpenCV_INCLUDE_DIRS})
target_link_libraries(massage_cell_session_report PUBLIC ${OpenCV_LIBS})
install(TARGETS massage_cell_session_report ARCHIVE DESTINATION ${CATKIN_PACKAGE_LIB_DESTINATION})
