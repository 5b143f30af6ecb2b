// What the report's files share (private to src/session/).
#pragma once

#include <string>

#include "massage_cell/session/report.h"

namespace massage_cell::session::detail {

/// printf-style formatting of up to three numbers.
std::string format(const char* fmt, double a, double b = 0.0, double c = 0.0);
/// A force trace's figures in words: "peak 31.2 N, 1.8 of 2.0 s of hold within ±10 % of the set-point (90 %)".
std::string forceLine(const ForceFigures& figures);

}  // namespace massage_cell::session::detail
