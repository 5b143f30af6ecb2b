// Small command-line helpers shared by the tools: typed option values with
// messages naming the option, and a table-driven parser. Usage errors are
// UsageError (tools exit 2 on them); everything else exits 1.
#pragma once

#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdarg>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <iostream>
#include <limits>
#include <map>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

namespace massage_cell::tools {

class UsageError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// printf into a string (of any length).
inline std::string format(const char* fmt, ...) __attribute__((format(printf, 1, 2)));
inline std::string format(const char* fmt, ...) {
  va_list args, again;
  va_start(args, fmt);
  va_copy(again, args);
  const int n = std::vsnprintf(nullptr, 0, fmt, args);
  va_end(args);
  std::string out(n > 0 ? static_cast<std::size_t>(n) : 0, '\0');
  if (n > 0) std::vsnprintf(out.data(), out.size() + 1, fmt, again);
  va_end(again);
  return out;
}

inline void require(bool ok, const std::string& message) {
  if (!ok) throw UsageError(message);
}

inline bool startsWithSpace(const std::string& s) {
  return !s.empty() && std::isspace(static_cast<unsigned char>(s[0]));
}

inline int parseInt(const std::string& option, const std::string& text) {
  char* end = nullptr;
  errno = 0;
  const long v = std::strtol(text.c_str(), &end, 10);
  if (text.empty() || startsWithSpace(text) || *end != '\0') {
    throw UsageError(option + ": expected an integer, got '" + text + "'");
  }
  if (errno == ERANGE || v < std::numeric_limits<int>::min() || v > std::numeric_limits<int>::max()) {
    throw UsageError(option + ": " + text + " is out of range");
  }
  return static_cast<int>(v);
}

inline double parseDouble(const std::string& option, const std::string& text) {
  char* end = nullptr;
  errno = 0;
  const double v = std::strtod(text.c_str(), &end);
  if (text.empty() || startsWithSpace(text) || *end != '\0') {
    throw UsageError(option + ": expected a number, got '" + text + "'");
  }
  if (!std::isfinite(v)) throw UsageError(option + ": expected a finite number, got '" + text + "'");
  if (errno == ERANGE) throw UsageError(option + ": " + text + " is out of range");
  return v;
}

inline std::uint32_t parseSeed(const std::string& option, const std::string& text) {
  char* end = nullptr;
  errno = 0;
  const unsigned long long v = std::strtoull(text.c_str(), &end, 10);
  if (text.empty() || !std::isdigit(static_cast<unsigned char>(text[0])) || *end != '\0') {
    throw UsageError(option + ": expected a non-negative integer, got '" + text + "'");
  }
  if (errno == ERANGE || v > std::numeric_limits<std::uint32_t>::max()) {
    throw UsageError(option + ": " + text + " is out of range (0.." +
                     std::to_string(std::numeric_limits<std::uint32_t>::max()) + ")");
  }
  return static_cast<std::uint32_t>(v);
}

/// "a,b,c" -> {"a", "b", "c"} (empty items dropped).
inline std::vector<std::string> splitList(const std::string& text) {
  std::vector<std::string> out;
  std::stringstream s(text);
  for (std::string item; std::getline(s, item, ',');) {
    if (!item.empty()) out.push_back(item);
  }
  return out;
}

/// Options that take a value, and flags that do not.
struct OptionTable {
  std::map<std::string, std::function<void(const std::string& option, const std::string& value)>> values;
  std::map<std::string, std::function<void()>> flags;
};

/// Parses argv against the table; prints `usage` and returns false on
/// --help / -h. Throws UsageError for unknown options, missing values and
/// stray arguments.
inline bool parseArguments(int argc, char** argv, const OptionTable& table, const char* usage) {
  const std::vector<std::string> args(argv + 1, argv + argc);
  for (std::size_t i = 0; i < args.size(); ++i) {
    const std::string& option = args[i];
    if (option == "--help" || option == "-h") {
      std::cout << usage;
      return false;
    }
    if (const auto flag = table.flags.find(option); flag != table.flags.end()) {
      flag->second();
      continue;
    }
    const auto setter = table.values.find(option);
    if (setter == table.values.end()) {
      throw UsageError(option.rfind("-", 0) == 0 ? "unknown option '" + option + "'"
                                                 : "unexpected argument '" + option + "'");
    }
    // Every other option takes a value; another option in its place means it is missing.
    if (i + 1 >= args.size() || args[i + 1].rfind("--", 0) == 0) throw UsageError(option + ": missing value");
    setter->second(option, args[++i]);
  }
  return true;
}

/// main() of a tool: usage errors exit 2, other errors 1, both with a message.
template <typename Parse, typename Run>
int runTool(const char* name, Parse parse, Run run) {
  try {
    if (!parse()) return 0;
  } catch (const UsageError& e) {
    std::cerr << name << ": " << e.what() << " (see --help)\n";
    return 2;
  }
  try {
    run();
  } catch (const std::exception& e) {
    std::cerr << name << ": " << e.what() << "\n";
    return 1;
  }
  return 0;
}

}  // namespace massage_cell::tools
