// One error policy for all of bodybuilder.
//
// Programmer mistakes (a broken precondition) are assertions. Bad data and I/O failures are
// ordinary results: a function that can fail on its input returns Result<T>, whose Error names
// the file, the place in it (a JSON path such as "$.primitives[3].radii[1]", a line, a byte
// offset) and the reason. No exception crosses a public API of bodybuilder.
#pragma once

#include <cassert>
#include <string>
#include <utility>
#include <variant>

namespace bb {

struct Error {
  std::string file;    // file the problem is in; empty when not about a file
  std::string where;   // place inside the file: JSON path, "line 12", "byte 40"; may be empty
  std::string reason;  // what is wrong, for a person

  // "file: where: reason", leaving out empty parts.
  std::string message() const {
    std::string m;
    if (!file.empty()) m += file + ": ";
    if (!where.empty()) m += where + ": ";
    return m + reason;
  }
};

template <class T>
class [[nodiscard]] Result {
 public:
  Result(T value) : v_(std::move(value)) {}           // NOLINT: implicit on purpose
  Result(Error error) : v_(std::move(error)) {}       // NOLINT: implicit on purpose

  bool ok() const { return v_.index() == 0; }
  explicit operator bool() const { return ok(); }

  T& value() & { assert(ok()); return std::get<0>(v_); }
  const T& value() const& { assert(ok()); return std::get<0>(v_); }
  T&& value() && { assert(ok()); return std::get<0>(std::move(v_)); }
  T* operator->() { return &value(); }
  const T* operator->() const { return &value(); }
  T& operator*() & { return value(); }
  const T& operator*() const& { return value(); }

  const Error& error() const { assert(!ok()); return std::get<1>(v_); }

 private:
  std::variant<T, Error> v_;
};

// For functions that return nothing but may fail.
struct Ok {};
using Status = Result<Ok>;

}  // namespace bb
