// Checks of a glTF file's container and JSON before tinygltf 2.7 reads them (see gltf_document.h).
#include "gltf_document.h"

#include <cctype>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

namespace bb::runtime::detail {
namespace {

using json = nlohmann::json;

std::uint32_t u32_at(const unsigned char* b, std::size_t at) {  // little-endian, whatever the host
  return std::uint32_t{b[at]} | std::uint32_t{b[at + 1]} << 8 | std::uint32_t{b[at + 2]} << 16 |
         std::uint32_t{b[at + 3]} << 24;
}

constexpr std::uint32_t kChunkJson = 0x4E4F534A;  // "JSON"
constexpr std::uint32_t kChunkBin = 0x004E4942;   // "BIN\0"

// Four bytes as a person reads them: "glTF", or their hex values where any is not printable.
std::string four_bytes(const unsigned char* b) {
  bool printable = true;
  for (int i = 0; i < 4; ++i) printable = printable && b[i] >= 0x20 && b[i] < 0x7f;
  char text[32];
  if (printable)
    std::snprintf(text, sizeof text, "\"%c%c%c%c\"", b[0], b[1], b[2], b[3]);
  else
    std::snprintf(text, sizeof text, "bytes %02x %02x %02x %02x", b[0], b[1], b[2], b[3]);
  return text;
}

// ---- the JSON text
// --------------------------------------------------------------------------------------

// The offset of the bracket that nests deeper than kMaxJsonDepth, if any (exact for valid JSON;
// invalid JSON is refused by the parser, which does not recurse).
std::optional<std::size_t> too_deep(std::string_view text) {
  int depth = 0;
  bool in_string = false;
  for (std::size_t i = 0; i < text.size(); ++i) {
    const char ch = text[i];
    if (in_string) {
      if (ch == '\\')
        ++i;
      else if (ch == '"')
        in_string = false;
    } else if (ch == '"') {
      in_string = true;
    } else if (ch == '[' || ch == '{') {
      if (++depth > kMaxJsonDepth) return i;
    } else if (ch == ']' || ch == '}') {
      --depth;
    }
  }
  return std::nullopt;
}

// nlohmann's DOM builder, keeping the offset where parsing stopped: a number beyond a double's
// range ("1e400") is an out_of_range exception, which does not carry the offset that syntax
// errors do.
struct DomBuilder : nlohmann::detail::json_sax_dom_parser<json> {
  std::size_t stop = 0;
  explicit DomBuilder(json& j) : json_sax_dom_parser<json>(j, true) {}
  template <class Exception>
  bool parse_error(std::size_t byte, const std::string& token, const Exception& ex) {
    stop = byte;
    return json_sax_dom_parser<json>::parse_error(byte, token, ex);
  }
};

// A problem found in the document; thrown inside this file only, and returned as a bb::Error.
struct Fail {
  std::string where, reason;
};
[[noreturn]] void fail(std::string where, std::string reason) {
  throw Fail{std::move(where), std::move(reason)};
}

std::string at(const std::string& w, const char* key) { return w + "." + key; }
std::string at(const std::string& w, std::size_t i) { return w + "[" + std::to_string(i) + "]"; }

std::string number_text(double v) {
  char b[32];
  std::snprintf(b, sizeof b, "%g", v);
  return b;
}

const json* find(const json& o, const char* key) {
  auto it = o.find(key);
  return it == o.end() ? nullptr : &*it;
}

const json& object(const json& v, const std::string& w) {
  if (!v.is_object()) fail(w, std::string("expected an object, got ") + v.type_name());
  return v;
}

const json& array(const json& v, const std::string& w) {
  if (!v.is_array()) fail(w, std::string("expected an array, got ") + v.type_name());
  return v;
}

const json& need(const json& o, const std::string& w, const char* key) {
  if (const json* v = find(o, key)) return *v;
  fail(w, std::string("missing required property \"") + key + "\"");
}

// A whole number as tinygltf reads one: a JSON integer from `least` up. tinygltf ignores an
// optional integer written as 1.0 or 1e0, and refuses a required one without saying where, so both
// are named here.
std::uint64_t whole(const json& v, const std::string& w, std::uint64_t least = 0) {
  if (v.is_number_unsigned() && v.get<std::uint64_t>() >= least) return v.get<std::uint64_t>();
  if (v.is_number_integer())
    fail(w, "is " + std::to_string(v.get<std::int64_t>()) + "; it must be " +
                std::to_string(least) + " or more");
  if (v.is_number_float()) {
    const double d = v.get<double>();
    if (d == std::floor(d) && d >= double(least) && d < 9007199254740992.0)
      fail(
          w,
          "is written " + v.dump() +
              ": this loader (tinygltf 2.7) reads integers written without a fraction or exponent");
    fail(w, "is " + number_text(d) + ", not a whole number from " + std::to_string(least) +
                " to 2^53");
  }
  fail(w, std::string("expected an integer, got ") + v.type_name());
}

// A material's colour factor: an array of `count` numbers (tinygltf refuses another length
// without saying where).
void factor(const json& v, const std::string& w, std::size_t count) {
  for (std::size_t i = 0; i < array(v, w).size(); ++i)
    if (!v[i].is_number()) fail(at(w, i), std::string("expected a number, got ") + v[i].type_name());
  if (v.size() != count)
    fail(w, "has " + std::to_string(v.size()) + " numbers; it must have " + std::to_string(count));
}

const std::string& text(const json& v, const std::string& w) {
  if (!v.is_string()) fail(w, std::string("expected a string, got ") + v.type_name());
  return v.get_ref<const std::string&>();
}

// `v`, at `w`: an index into the document's top-level array `target`.
void index_into(const json& v, const std::string& w, const json& doc, const char* target) {
  const std::uint64_t i = whole(v, w);
  const json* list = find(doc, target);
  const std::size_t n = list ? list->size() : 0;
  if (i >= n)
    fail(w, std::string(target) + "[" + std::to_string(i) + "] does not exist (the file has " +
                std::to_string(n) + ")");
}

// The reference `o.key` (required or not): an index into the top-level array `target`.
void reference(const json& o, const std::string& w, const char* key, bool required, const json& doc,
               const char* target) {
  if (const json* v = find(o, key))
    index_into(*v, at(w, key), doc, target);
  else if (required)
    need(o, w, key);
}

// Each element of the array `o.key` (required or not): an index into `target`.
void references(const json& o, const std::string& w, const char* key, bool required,
                const json& doc, const char* target) {
  const json* v = find(o, key);
  if (!v) {
    if (required) need(o, w, key);
    return;
  }
  const json& list = array(*v, at(w, key));
  for (std::size_t k = 0; k < list.size(); ++k) index_into(list[k], at(at(w, key), k), doc, target);
}

// An object of attribute name -> accessor index (a primitive's attributes, a morph target).
void attribute_map(const json& v, const std::string& w, const json& doc) {
  for (const auto& [name, value] : object(v, w).items())
    index_into(value, w + "." + name, doc, "accessors");
}

// tinygltf's base64 decoder reads up to the first '=' or character outside the alphabet.
std::size_t base64_bytes(std::string_view b64) {
  std::size_t n = 0;
  while (n < b64.size() &&
         (std::isalnum(static_cast<unsigned char>(b64[n])) || b64[n] == '+' || b64[n] == '/'))
    ++n;
  return n * 3 / 4;
}

// The media types tinygltf decodes from a data: URI.
constexpr const char* kDataUriHeaders[] = {"data:application/octet-stream;base64,",
                                           "data:image/jpeg;base64,",
                                           "data:image/png;base64,",
                                           "data:image/bmp;base64,",
                                           "data:image/gif;base64,",
                                           "data:text/plain;base64,",
                                           "data:application/gltf-buffer;base64,"};

// A uri's %XX escapes decoded, as tinygltf does before it looks for the file.
std::string percent_decoded(const std::string& uri) {
  std::string out;
  for (std::size_t i = 0; i < uri.size(); ++i) {
    if (uri[i] == '%' && i + 2 < uri.size() &&
        std::isxdigit(static_cast<unsigned char>(uri[i + 1])) &&
        std::isxdigit(static_cast<unsigned char>(uri[i + 2]))) {
      out += static_cast<char>(std::stoi(uri.substr(i + 1, 2), nullptr, 16));
      i += 2;
    } else {
      out += uri[i];
    }
  }
  return out;
}

// The file a uri that is not a data: URI names: a path relative to the glTF file (tinygltf joins
// it to the file's folder), %XX escapes decoded. A URI with a scheme (http:, file:) is not
// fetched, and an absolute path is not one tinygltf can join, so both are refused, as is a name
// that is not a file there.
std::filesystem::path external_file(const std::string& u, const std::string& w,
                                    const std::string& path) {
  namespace fs = std::filesystem;
  if (u.empty()) fail(w, "is empty; it must name a file beside " + path + " or hold a data: URI");
  std::size_t k = 0;
  if (std::isalpha(static_cast<unsigned char>(u[0])))
    for (k = 1; k < u.size() && (std::isalnum(static_cast<unsigned char>(u[k])) || u[k] == '+' ||
                                 u[k] == '-' || u[k] == '.');
         ++k) {
    }
  const std::string reads =
      "this loader reads data: URIs and files named relative to the folder of " + path;
  // A Windows drive ("C:\x.png", "C:/x.png") is an absolute path, not a one-letter scheme.
  if (k == 1 && u.size() > 2 && u[1] == ':' && (u[2] == '\\' || u[2] == '/'))
    fail(w, "names the absolute path \"" + u + "\": " + reads);
  if (k > 0 && k < u.size() && u[k] == ':')
    fail(w, "names \"" + u + "\", a URI with the scheme " + u.substr(0, k + 1) +
                ", which is not fetched: " + reads);
  const std::string name = percent_decoded(u);
  if (name[0] == '/' || name[0] == '\\') fail(w, "names the absolute path \"" + u + "\": " + reads);
  const fs::path file = fs::path(path).parent_path() / name;
  std::error_code ec;
  if (!fs::is_regular_file(file, ec))
    fail(w, "names \"" + u + "\", which is not a file beside " + path);
  return file;
}

bool is_meshopt_fallback(const json& buffer) {
  const json* ext = find(buffer, "extensions");
  const json* e = ext && ext->is_object() ? find(*ext, "EXT_meshopt_compression") : nullptr;
  const json* fb = e && e->is_object() ? find(*e, "fallback") : nullptr;
  return fb && fb->is_boolean() && fb->get<bool>();
}

// A buffer's data: where it comes from, and that it holds byteLength bytes.
void buffer_data(const json& b, const std::string& w, std::size_t index, std::uint64_t length,
                 const std::string& path, const GlbLayout* glb) {
  const json* uri = find(b, "uri");
  if (!uri) {
    if (is_meshopt_fallback(b))
      return;  // never read: its views are decoded from the compressed buffer
    if (!glb)
      fail(w,
           "has no uri: a .gltf file's buffer must name its data (only a .glb's may take its BIN "
           "chunk)");
    if (!glb->has_bin) fail(w, "has no uri, and the .glb has no BIN chunk for it to take");
    // tinygltf gives the BIN chunk to every buffer without a uri, the spec to the first only.
    if (index > 0 && length > glb->bin_length)
      fail(w,
           "has no uri, and only a .glb's first buffer takes the BIN chunk: this loader has no "
           "data for it");
    if (length > glb->bin_length)
      fail(at(w, "byteLength"), std::to_string(length) + " is more than the BIN chunk's " +
                                    std::to_string(glb->bin_length) + " bytes");
    return;
  }
  const std::string& u = text(*uri, at(w, "uri"));
  if (u.rfind("data:", 0) == 0) {
    for (const char* h : kDataUriHeaders) {
      if (u.rfind(h, 0) != 0) continue;
      const std::size_t n = base64_bytes(std::string_view(u).substr(std::strlen(h)));
      if (n != length)
        fail(at(w, "uri"), "the data: URI holds " + std::to_string(n) + " bytes; byteLength says " +
                               std::to_string(length));
      return;
    }
    fail(at(w, "uri"),
         "a data: URI this loader does not read (it reads base64 data of type "
         "application/octet-stream or application/gltf-buffer)");
  }
  namespace fs = std::filesystem;
  const fs::path file = external_file(u, at(w, "uri"), path);
  std::error_code ec;
  const std::uintmax_t size = fs::file_size(file, ec);
  if (ec) fail(at(w, "uri"), "cannot read " + file.string() + ": " + ec.message());
  if (size != length)
    fail(at(w, "uri"), file.string() + " holds " + std::to_string(size) +
                           " bytes; byteLength says " + std::to_string(length));
}

// The top-level arrays glTF 2.0 defines; each must be an array of objects.
constexpr const char* kDictionaries[] = {
    "accessors", "animations", "buffers",  "bufferViews", "cameras", "images",  "materials",
    "meshes",    "nodes",      "samplers", "scenes",      "skins",   "textures"};

// Visits each element of the top-level array `name` (absent: none) as (element, its path, its
// index).
template <class F>
void each(const json& doc, const char* name, F&& f) {
  const json* list = find(doc, name);
  if (!list) return;
  for (std::size_t i = 0; i < list->size(); ++i)
    f((*list)[i], "$." + std::string(name) + "[" + std::to_string(i) + "]", i);
}

void check_document(const json& doc, const std::string& path, const GlbLayout* glb) {
  object(doc, "$");
  const json& asset = object(need(doc, "$", "asset"), "$.asset");
  text(need(asset, "$.asset", "version"), "$.asset.version");
  for (const char* name : kDictionaries) {
    const json* list = find(doc, name);
    if (!list) continue;
    const std::string w = std::string("$.") + name;
    array(*list, w);
    for (std::size_t i = 0; i < list->size(); ++i) object((*list)[i], at(w, i));
  }
  for (const char* name : {"extensionsUsed", "extensionsRequired"}) {
    if (const json* list = find(doc, name))
      for (std::size_t i = 0; i < array(*list, std::string("$.") + name).size(); ++i)
        text((*list)[i], at(std::string("$.") + name, i));
  }
  reference(doc, "$", "scene", false, doc, "scenes");

  each(doc, "buffers", [&](const json& b, const std::string& w, std::size_t i) {
    const std::uint64_t length = whole(need(b, w, "byteLength"), at(w, "byteLength"), 1);
    buffer_data(b, w, i, length, path, glb);
  });
  each(doc, "bufferViews", [&](const json& v, const std::string& w, std::size_t) {
    reference(v, w, "buffer", true, doc, "buffers");
    whole(need(v, w, "byteLength"), at(w, "byteLength"), 1);
    if (const json* s = find(v, "byteStride")) {
      const std::uint64_t stride = whole(*s, at(w, "byteStride"));
      if (stride > 252 || stride % 4 != 0)
        fail(at(w, "byteStride"), std::to_string(stride) + " is not a multiple of 4 up to 252");
    }
  });
  each(doc, "accessors", [&](const json& a, const std::string& w, std::size_t) {
    reference(a, w, "bufferView", false, doc, "bufferViews");
    const std::uint64_t ct = whole(need(a, w, "componentType"), at(w, "componentType"));
    if (ct < 5120 || ct > 5130)
      fail(at(w, "componentType"),
           std::to_string(ct) + " is not a glTF component type (5120 to 5126)");
    whole(need(a, w, "count"), at(w, "count"));
    const std::string& type = text(need(a, w, "type"), at(w, "type"));
    if (type != "SCALAR" && type != "VEC2" && type != "VEC3" && type != "VEC4" && type != "MAT2" &&
        type != "MAT3" && type != "MAT4")
      fail(at(w, "type"),
           "\"" + type + "\" is not an accessor type (SCALAR, VEC2, VEC3, VEC4, MAT2, MAT3, MAT4)");
    if (const json* sp = find(a, "sparse")) {
      const std::string sw = at(w, "sparse");
      object(*sp, sw);
      whole(need(*sp, sw, "count"), at(sw, "count"));
      const json& ind = object(need(*sp, sw, "indices"), at(sw, "indices"));
      reference(ind, at(sw, "indices"), "bufferView", true, doc, "bufferViews");
      whole(need(ind, at(sw, "indices"), "componentType"), at(at(sw, "indices"), "componentType"));
      const json& val = object(need(*sp, sw, "values"), at(sw, "values"));
      reference(val, at(sw, "values"), "bufferView", true, doc, "bufferViews");
    }
  });
  each(doc, "images", [&](const json& im, const std::string& w, std::size_t) {
    const bool view = find(im, "bufferView") != nullptr, uri = find(im, "uri") != nullptr;
    if (view == uri)
      fail(w, view ? "has both a uri and a bufferView; it may have one"
                   : "has neither a uri nor a bufferView");
    if (uri) {
      // A file beside the glTF (tinygltf would leave a missing one empty and the material
      // untextured, without a word); a data: URI is decoded by the image callback, which names
      // what it cannot decode.
      const std::string& u = text(*find(im, "uri"), at(w, "uri"));
      if (u.rfind("data:", 0) != 0) external_file(u, at(w, "uri"), path);
    }
    reference(im, w, "bufferView", false, doc, "bufferViews");
  });
  each(doc, "textures", [&](const json& t, const std::string& w, std::size_t) {
    reference(t, w, "source", false, doc, "images");
    reference(t, w, "sampler", false, doc, "samplers");
  });
  each(doc, "materials", [&](const json& m, const std::string& w, std::size_t) {
    auto texture_info = [&](const json& o, const std::string& ow, const char* key) {
      if (const json* ti = find(o, key))
        reference(object(*ti, at(ow, key)), at(ow, key), "index", true, doc, "textures");
    };
    if (const json* pbr = find(m, "pbrMetallicRoughness")) {
      const std::string pw = at(w, "pbrMetallicRoughness");
      object(*pbr, pw);
      if (const json* f = find(*pbr, "baseColorFactor")) factor(*f, at(pw, "baseColorFactor"), 4);
      texture_info(*pbr, pw, "baseColorTexture");
      texture_info(*pbr, pw, "metallicRoughnessTexture");
    }
    if (const json* f = find(m, "emissiveFactor")) factor(*f, at(w, "emissiveFactor"), 3);
    for (const char* key : {"normalTexture", "occlusionTexture", "emissiveTexture"})
      texture_info(m, w, key);
  });
  each(doc, "meshes", [&](const json& mesh, const std::string& w, std::size_t) {
    const json& prims = array(need(mesh, w, "primitives"), at(w, "primitives"));
    for (std::size_t p = 0; p < prims.size(); ++p) {
      const std::string pw = at(at(w, "primitives"), p);
      const json& prim = object(prims[p], pw);
      attribute_map(need(prim, pw, "attributes"), at(pw, "attributes"), doc);
      reference(prim, pw, "material", false, doc, "materials");
      reference(prim, pw, "indices", false, doc, "accessors");
      if (const json* ind = find(prim, "indices")) {
        const std::size_t i = ind->get<std::size_t>();
        if (!find((*find(doc, "accessors"))[i], "bufferView"))
          fail(at(pw, "indices"), "accessors[" + std::to_string(i) +
                                      "] has no bufferView (all its indices would be 0)");
      }
      if (const json* targets = find(prim, "targets"))
        for (std::size_t t = 0; t < array(*targets, at(pw, "targets")).size(); ++t)
          attribute_map((*targets)[t], at(at(pw, "targets"), t), doc);
    }
  });
  each(doc, "nodes", [&](const json& n, const std::string& w, std::size_t) {
    references(n, w, "children", false, doc, "nodes");
    reference(n, w, "mesh", false, doc, "meshes");
    reference(n, w, "skin", false, doc, "skins");
    reference(n, w, "camera", false, doc, "cameras");
  });
  each(doc, "scenes", [&](const json& s, const std::string& w, std::size_t) {
    references(s, w, "nodes", false, doc, "nodes");
  });
  each(doc, "skins", [&](const json& s, const std::string& w, std::size_t) {
    references(s, w, "joints", true, doc, "nodes");
    reference(s, w, "inverseBindMatrices", false, doc, "accessors");
    reference(s, w, "skeleton", false, doc, "nodes");
  });
  each(doc, "animations", [&](const json& a, const std::string& w, std::size_t) {
    const json& samplers = array(need(a, w, "samplers"), at(w, "samplers"));
    for (std::size_t s = 0; s < samplers.size(); ++s) {
      const std::string sw = at(at(w, "samplers"), s);
      const json& smp = object(samplers[s], sw);
      reference(smp, sw, "input", true, doc, "accessors");
      reference(smp, sw, "output", true, doc, "accessors");
    }
    const json& channels = array(need(a, w, "channels"), at(w, "channels"));
    for (std::size_t c = 0; c < channels.size(); ++c) {
      const std::string cw = at(at(w, "channels"), c);
      const json& ch = object(channels[c], cw);
      const std::uint64_t s = whole(need(ch, cw, "sampler"), at(cw, "sampler"));
      if (s >= samplers.size())
        fail(at(cw, "sampler"), "sampler " + std::to_string(s) +
                                    " does not exist (the animation has " +
                                    std::to_string(samplers.size()) + ")");
      const std::string tw = at(cw, "target");
      const json& target = object(need(ch, cw, "target"), tw);
      reference(target, tw, "node", true, doc, "nodes");
      text(need(target, tw, "path"), at(tw, "path"));
    }
  });
  each(doc, "cameras", [&](const json& c, const std::string& w, std::size_t) {
    const std::string& type = text(need(c, w, "type"), at(w, "type"));
    if (type != "perspective" && type != "orthographic")
      fail(at(w, "type"), "\"" + type + "\" is not a camera type (perspective, orthographic)");
    const json& p = object(need(c, w, type.c_str()), at(w, type.c_str()));
    const std::string pw = at(w, type.c_str());
    static const std::vector<const char*> kPerspective = {"yfov", "znear"},
                                          kOrthographic = {"xmag", "ymag", "zfar", "znear"};
    for (const char* key : type == "perspective" ? kPerspective : kOrthographic)
      if (!need(p, pw, key).is_number())
        fail(at(pw, key), std::string("expected a number, got ") + p[key].type_name());
  });
}

}  // namespace

Result<GlbLayout> check_glb_container(const unsigned char* b, std::size_t size,
                                      const std::string& path) {
  auto err = [&](std::size_t at, const std::string& reason) {
    return Error{path, "byte " + std::to_string(at), reason};
  };
  if (size < 12)
    return err(
        0, "the 12-byte GLB header is cut short: the file has " + std::to_string(size) + " bytes");
  if (std::memcmp(b, "glTF", 4) != 0)
    return err(0, "not a GLB file: it starts with " + four_bytes(b) + ", not \"glTF\"");
  if (const std::uint32_t version = u32_at(b, 4); version != 2)
    return err(4, "GLB version " + std::to_string(version) + "; this loader reads version 2");
  const std::size_t length = u32_at(b, 8);
  if (length > size)
    return err(8, "the header gives the file's length as " + std::to_string(length) +
                      " bytes; it has " + std::to_string(size));
  if (length < 20)
    return err(8, "the header gives the file's length as " + std::to_string(length) +
                      " bytes, too few for a chunk (20 at least)");
  GlbLayout out;
  out.json_at = 20;
  out.json_length = u32_at(b, 12);
  if (const std::uint32_t type = u32_at(b, 16); type != kChunkJson)
    return err(16, "the first chunk's type is " + four_bytes(b + 16) +
                       ", not \"JSON\": a .glb starts with its JSON chunk");
  if (out.json_length == 0) return err(12, "the JSON chunk is empty");
  if (out.json_length > length - 20)
    return err(12, "the JSON chunk's length " + std::to_string(out.json_length) +
                       " runs past the end of the file (" + std::to_string(length) + " bytes)");
  const std::size_t p = 20 + out.json_length;  // the next chunk's header
  if (p == length) return out;
  if (length - p < 12)
    return err(p, std::to_string(length - p) +
                      " bytes follow the JSON chunk: too few for a BIN chunk (an 8-byte header and "
                      "4 bytes or more)");
  const std::uint32_t bin_length = u32_at(b, p), type = u32_at(b, p + 4);
  if (type == kChunkJson) return err(p + 4, "a second JSON chunk: a .glb has one");
  if (type != kChunkBin)
    return err(p + 4, "the chunk after the JSON chunk is of type " + four_bytes(b + p + 4) +
                          ", not \"BIN\"");
  if (bin_length < 4 || bin_length % 4 != 0)
    return err(p, "the BIN chunk's length " + std::to_string(bin_length) +
                      " is not a multiple of 4 from 4 up");
  if (bin_length > length - p - 8)
    return err(p, "the BIN chunk's length " + std::to_string(bin_length) +
                      " runs past the end of the file (" + std::to_string(length) + " bytes)");
  out.has_bin = true;
  out.bin_length = bin_length;
  return out;
}

Status check_gltf_json(std::string_view text, const std::string& path, const GlbLayout* glb) {
  // A place in the text: a byte of the file in a .glb, a line and column in a .gltf.
  auto place = [&](std::size_t offset) {
    if (glb) return "byte " + std::to_string(glb->json_at + offset);
    std::size_t line = 1, column = 1;
    for (std::size_t i = 0; i < offset && i < text.size(); ++i) {
      if (text[i] == '\n')
        ++line, column = 1;
      else
        ++column;
    }
    return "line " + std::to_string(line) + ", column " + std::to_string(column);
  };
  if (auto at = too_deep(text))
    return Error{path, place(*at),
                 "the JSON nests deeper than " + std::to_string(kMaxJsonDepth) + " levels"};
  json doc;
  DomBuilder builder(doc);
  try {
    json::sax_parse(text.begin(), text.end(), &builder);
  } catch (const json::exception& e) {
    std::string what = e.what();
    auto p = what.find("syntax error");
    if (p == std::string::npos && (p = what.find("] ")) != std::string::npos)
      p += 2;  // past "[json.exception...] "
    return Error{path, place(builder.stop > 0 ? builder.stop - 1 : 0),
                 "invalid JSON: " + (p == std::string::npos ? what : what.substr(p))};
  }
  try {
    check_document(doc, path, glb);
  } catch (const Fail& f) {
    return Error{path, f.where, f.reason};
  }
  return Ok{};
}

}  // namespace bb::runtime::detail
