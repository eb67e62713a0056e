// Internal: reading JSON with errors that carry the JSON path. Parse functions throw
// JsonError inside the modeler; the public entry points catch it and return bb::Error.
#pragma once

#include <algorithm>
#include <cstdio>
#include <iterator>
#include <limits>
#include <set>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <string_view>
#include <vector>

#include <glm/glm.hpp>
#include <nlohmann/json.hpp>

#include "bb/result.h"

namespace bb::modeler::detail {

using nlohmann::json;

struct JsonError {
  std::string where;
  std::string reason;
};

[[noreturn]] inline void fail(const std::string& where, const std::string& reason) {
  throw JsonError{where, reason};
}

// `v` as an error message shows it: shortest form, "1e+30" rather than thirty digits.
inline std::string number_text(double v) {
  char b[32];
  std::snprintf(b, sizeof b, "%g", v);
  return b;
}

inline std::string at(const std::string& path, const std::string& key) { return path + "." + key; }
inline std::string at(const std::string& path, size_t i) {
  return path + "[" + std::to_string(i) + "]";
}

inline const char* type_name(const json& j) { return j.type_name(); }

inline const json& member(const json& obj, const std::string& path, const char* key) {
  if (!obj.is_object()) fail(path, std::string("expected an object, got ") + type_name(obj));
  auto it = obj.find(key);
  if (it == obj.end()) fail(path, std::string("missing required key \"") + key + "\"");
  return *it;
}

inline double number(const json& j, const std::string& path) {
  if (!j.is_number()) fail(path, std::string("expected a number, got ") + type_name(j));
  double v = j.get<double>();
  if (!std::isfinite(v)) fail(path, "expected a finite number");
  // Body and skeleton values are kept as floats: past their range a value became "inf" in the
  // range checks' messages (a radius of 1e300 was "got inf").
  if (std::abs(v) > static_cast<double>(std::numeric_limits<float>::max())) {
    char text[32];
    std::snprintf(text, sizeof text, "%g", v);
    fail(path, std::string("expected a number a float holds, within +-3.4e38 (got ") + text + ")");
  }
  return v;
}

inline std::string string(const json& j, const std::string& path) {
  if (!j.is_string()) fail(path, std::string("expected a string, got ") + type_name(j));
  return j.get<std::string>();
}

inline glm::vec3 vec3(const json& j, const std::string& path) {
  if (!j.is_array() || j.size() != 3)
    fail(path, std::string("expected an array of 3 numbers, got ") +
                   (j.is_array() ? std::to_string(j.size()) + " elements" : type_name(j)));
  return glm::vec3(number(j[0], at(path, 0)), number(j[1], at(path, 1)), number(j[2], at(path, 2)));
}

inline const json& array(const json& j, const std::string& path) {
  if (!j.is_array()) fail(path, std::string("expected an array, got ") + type_name(j));
  return j;
}

// An iterator over the text that records how far the parser has read (for the line of an error
// found in a SAX callback, where nlohmann gives no position).
struct CountingIterator {
  using iterator_category = std::input_iterator_tag;
  using value_type = char;
  using difference_type = std::ptrdiff_t;
  using pointer = const char*;
  using reference = const char&;
  const char* p = nullptr;
  const char** read_to = nullptr;
  reference operator*() const { return *p; }
  CountingIterator& operator++() {
    *read_to = ++p;
    return *this;
  }
  CountingIterator operator++(int) {
    CountingIterator old = *this;
    ++*this;
    return old;
  }
  bool operator==(const CountingIterator& o) const { return p == o.p; }
  bool operator!=(const CountingIterator& o) const { return p != o.p; }
};

// nlohmann's DOM builder, keeping the byte offset where parsing stopped (a number beyond double's range,
// "1e400", is an out_of_range exception, which does not carry the offset its syntax errors do), and
// refusing a key that appears twice in one object (nlohmann keeps the last silently): the error names
// the object's JSON path, the key and its line.
struct DomBuilder : nlohmann::detail::json_sax_dom_parser<json> {
  using Base = nlohmann::detail::json_sax_dom_parser<json>;
  std::size_t stop = 0;
  std::string_view text;
  const char* read_to = nullptr;  // what the parser has read, through CountingIterator
  struct Level {
    bool array = false;
    std::size_t count = 0;  // an array's elements so far
    std::string key;        // an object's current key
    std::set<std::string> keys;
  };
  std::vector<Level> levels;

  DomBuilder(json& j, std::string_view t) : Base(j, true), text(t), read_to(t.data()) {}

  std::string path() const {  // of the innermost object or array
    std::string p = "$";
    for (std::size_t i = 0; i + 1 < levels.size(); ++i)
      p = levels[i].array ? at(p, levels[i].count - 1) : at(p, levels[i].key);
    return p;
  }
  void element() {
    if (!levels.empty() && levels.back().array) ++levels.back().count;
  }

  bool null() { return element(), Base::null(); }
  bool boolean(bool v) { return element(), Base::boolean(v); }
  bool number_integer(number_integer_t v) { return element(), Base::number_integer(v); }
  bool number_unsigned(number_unsigned_t v) { return element(), Base::number_unsigned(v); }
  bool number_float(number_float_t v, const string_t& s) { return element(), Base::number_float(v, s); }
  bool string(string_t& v) { return element(), Base::string(v); }
  bool start_object(std::size_t n) {
    element();
    levels.push_back({});
    return Base::start_object(n);
  }
  bool key(string_t& k) {
    Level& l = levels.back();
    if (!l.keys.insert(k).second) {
      const std::size_t read = static_cast<std::size_t>(read_to - text.data());
      const auto line = 1 + std::count(text.begin(), text.begin() + static_cast<std::ptrdiff_t>(read), '\n');
      fail(path(), "duplicate key \"" + k + "\" (line " + std::to_string(line) + "): a key may appear once in an object");
    }
    l.key = k;
    return Base::key(k);
  }
  bool end_object() {
    levels.pop_back();
    return Base::end_object();
  }
  bool start_array(std::size_t n) {
    element();
    levels.push_back({true});
    return Base::start_array(n);
  }
  bool end_array() {
    levels.pop_back();
    return Base::end_array();
  }
  template <class Exception>
  bool parse_error(std::size_t byte, const std::string& token, const Exception& ex) {
    stop = byte;
    return Base::parse_error(byte, token, ex);
  }
};

// Parses text, turning syntax errors (and numbers out of range) into "line L, column C" places and a
// duplicate key into an error at its object's JSON path.
inline json parse_text(std::string_view text) {
  json doc;
  DomBuilder builder(doc, text);
  try {
    CountingIterator first{text.data(), &builder.read_to}, last{text.data() + text.size(), &builder.read_to};
    json::sax_parse(first, last, &builder);
    return doc;
  } catch (const json::exception& e) {
    // Translate the byte offset into line and column.
    size_t line = 1, col = 1;
    for (size_t i = 0; i + 1 < builder.stop && i < text.size(); ++i) {
      if (text[i] == '\n') { ++line; col = 1; } else { ++col; }
    }
    std::string what = e.what();
    auto p = what.find("syntax error");
    if (p == std::string::npos && (p = what.find("] ")) != std::string::npos) p += 2;  // past "[json.exception...] "
    fail("line " + std::to_string(line) + ", column " + std::to_string(col),
         "invalid JSON: " + (p == std::string::npos ? what : what.substr(p)));
  }
}

inline Result<std::string> read_file(const std::string& path) {
  // A directory opens and reads as an empty file: say what it is ("skeleton": "" names the body's folder).
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec)) return Error{path, "", "is a directory, not a file"};
  std::ifstream in(path, std::ios::binary);
  if (!in) return Error{path, "", "cannot open file (does it exist?)"};
  std::ostringstream ss;
  ss << in.rdbuf();
  if (in.bad()) return Error{path, "", "read error"};
  return ss.str();
}

}  // namespace bb::modeler::detail
