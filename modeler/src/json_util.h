// Internal: reading JSON with errors that carry the JSON path. Parse functions throw
// JsonError inside the modeler; the public entry points catch it and return bb::Error.
#pragma once

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <string_view>

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

// nlohmann's DOM builder, keeping the byte offset where parsing stopped: a number beyond double's range
// ("1e400") is an out_of_range exception, which does not carry the offset its syntax errors do.
struct DomBuilder : nlohmann::detail::json_sax_dom_parser<json> {
  std::size_t stop = 0;
  explicit DomBuilder(json& j) : json_sax_dom_parser<json>(j, true) {}
  template <class Exception>
  bool parse_error(std::size_t byte, const std::string& token, const Exception& ex) {
    stop = byte;
    return json_sax_dom_parser<json>::parse_error(byte, token, ex);
  }
};

// Parses text, turning syntax errors (and numbers out of range) into "line L, column C" places.
inline json parse_text(std::string_view text) {
  json doc;
  DomBuilder builder(doc);
  try {
    json::sax_parse(text.begin(), text.end(), &builder);
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
