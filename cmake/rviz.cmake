# rviz/cell.rviz: the cell in rviz (cell.launch rviz:=true). Its test (test/ros/CMakeLists.txt:
# rviz_cell.test under Xvfb) replays the bundled bag into hbds, cect, planar and the arm and compares
# screenshots with and without the RobotModel / PointCloud2 displays.
install(DIRECTORY rviz DESTINATION ${CATKIN_PACKAGE_SHARE_DESTINATION})
