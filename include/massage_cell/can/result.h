// A value or an error message: what the frame decoders and the config loader
// return, so that a malformed frame never throws through a receive loop.
#pragma once

#include <optional>
#include <stdexcept>
#include <string>
#include <utility>

namespace massage_cell::can {

template <typename T>
class Result {
 public:
  /// A successful result.
  static Result success(T value) {
    Result r;
    r.value_ = std::move(value);
    return r;
  }
  /// A failed result with a message saying what was wrong.
  static Result failure(std::string error) {
    Result r;
    r.error_ = std::move(error);
    return r;
  }
  bool ok() const { return value_.has_value(); }
  explicit operator bool() const { return ok(); }
  /// The value; throws std::logic_error (with the error text) when failed.
  const T& value() const {
    if (!value_) throw std::logic_error("Result::value() of a failed result: " + error_);
    return *value_;
  }
  const T& operator*() const { return value(); }
  const T* operator->() const { return &value(); }
  /// Empty when ok.
  const std::string& error() const { return error_; }

 private:
  std::optional<T> value_;
  std::string error_;
};

}  // namespace massage_cell::can
