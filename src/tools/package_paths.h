#pragma once
// Where the command-line tools find the package's files and the shared data sets, with no source-tree path
// compiled in: the package folder comes from roslib (ROS_PACKAGE_PATH: `source _build/devel/setup.bash`, or an
// installed package), the data from $MASSAGE_CELL_DATA or the folder `shared/data` beside the package's. A tool
// built without roslib (the static copies for the qemu guest) has no default: its options must name the files.

#include <cstdlib>
#include <stdexcept>
#include <string>

#ifdef MASSAGE_CELL_TOOLS_ROSLIB
#include <ros/package.h>
#endif

namespace massage_cell::tools {

/// The massage_cell package's folder; throws naming the fix when it cannot be found.
inline std::string packageDir() {
#ifdef MASSAGE_CELL_TOOLS_ROSLIB
  const std::string dir = ros::package::getPath("massage_cell");
  if (!dir.empty()) return dir;
  throw std::runtime_error(
      "the massage_cell package is not on ROS_PACKAGE_PATH (source _build/devel/setup.bash), so its default "
      "files cannot be found: source it or name the file with the tool's option");
#else
  throw std::runtime_error("this build of the tool has no package folder: name the file with the tool's option");
#endif
}

/// A file of the package, e.g. "config/arm.yaml".
inline std::string packageFile(const std::string& relative) { return packageDir() + "/" + relative; }

/// The shared data sets (middlebury2003, middlebury2005, multiview, back): $MASSAGE_CELL_DATA, else
/// `../shared/data` beside the package's folder.
inline std::string sharedDataDir() {
  if (const char* env = std::getenv("MASSAGE_CELL_DATA")) return env;
  return packageDir() + "/../shared/data";
}

/// One data set's folder: $`variable` if set, else `shared_data`/`folder`.
inline std::string dataFolder(const char* variable, const std::string& shared_data, const char* folder) {
  if (const char* env = std::getenv(variable)) return env;
  return shared_data + "/" + folder;
}

/// The Middlebury scenes (stereo/middlebury.h): $MASSAGE_CELL_MIDDLEBURY (2003) / $MASSAGE_CELL_MIDDLEBURY2005 if
/// set, else `shared_data`/middlebury2003 / middlebury2005.
inline std::string middleburyDir(const std::string& shared_data) {
  return dataFolder("MASSAGE_CELL_MIDDLEBURY", shared_data, "middlebury2003");
}
inline std::string middlebury2005Dir(const std::string& shared_data) {
  return dataFolder("MASSAGE_CELL_MIDDLEBURY2005", shared_data, "middlebury2005");
}

}  // namespace massage_cell::tools
