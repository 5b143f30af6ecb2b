// Where the planar tests find Merton College I (../shared/data, or
// $MASSAGE_CELL_DATA), and a reader of its plain-number files.
#pragma once

#include <cstdlib>
#include <fstream>
#include <string>
#include <vector>

namespace massage_cell::planar::test {

inline std::string dataRoot() {
  const char* env = std::getenv("MASSAGE_CELL_DATA");
  return env != nullptr ? std::string(env) : std::string(MASSAGE_CELL_SOURCE_DIR) + "/../shared/data";
}

inline std::string mertonFolder() { return dataRoot() + "/multiview/merton_college_1"; }

/// Rows of `per_row` numbers until the first that does not parse (2D/00N.corners, 3D/p3d, 3D/l3d).
inline std::vector<std::vector<double>> readNumbers(const std::string& path, int per_row) {
  std::ifstream in(path);
  std::vector<std::vector<double>> rows;
  std::vector<double> row(static_cast<std::size_t>(per_row));
  while (true) {
    for (double& v : row) {
      if (!(in >> v)) return rows;
    }
    rows.push_back(row);
  }
}

}  // namespace massage_cell::planar::test
