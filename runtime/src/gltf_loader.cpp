// glTF -> Model. tinygltf parses (Debian ships it as libtinygltf.so, so no implementation is
// compiled here); everything it hands back is validated before use: indices, accessor bounds,
// counts, finiteness, hierarchy loops.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include <glm/gtc/type_ptr.hpp>
#define GLM_ENABLE_EXPERIMENTAL
#include <glm/gtx/matrix_decompose.hpp>
#include <meshoptimizer.h>
#include <nlohmann/json.hpp>
#include <tiny_gltf.h>
#include <webp/decode.h>

#include "bb/runtime/model.h"
#include "gltf_document.h"

namespace bb::runtime {

namespace tg = tinygltf;

namespace {

std::string idx(const char* array, int i) { return std::string("$.") + array + "[" + std::to_string(i) + "]"; }

// The width and height a PNG or JPEG header gives, read before stb_image allocates its pixels from them; nothing
// for other formats, or a header too short to tell.
std::optional<std::pair<std::uint32_t, std::uint32_t>> png_or_jpeg_size(const unsigned char* b, int size) {
  const auto n = static_cast<std::size_t>(std::max(size, 0));
  auto be = [&](std::size_t at, int bytes) {
    std::uint32_t v = 0;
    for (int k = 0; k < bytes; ++k) v = v << 8 | b[at + k];
    return v;
  };
  if (n >= 24 && std::memcmp(b, "\x89PNG\r\n\x1a\n", 8) == 0 && std::memcmp(b + 12, "IHDR", 4) == 0)
    return std::make_pair(be(16, 4), be(20, 4));
  if (n < 4 || b[0] != 0xff || b[1] != 0xd8) return std::nullopt;
  for (std::size_t i = 2; i + 9 <= n;) {  // JPEG segments up to the frame header (SOF0 to SOF15)
    if (b[i] != 0xff) return std::nullopt;
    const unsigned m = b[i + 1];
    if (m == 0xff) { ++i; continue; }  // fill byte
    if (m == 0xd8 || m == 0x01 || (m >= 0xd0 && m <= 0xd7)) { i += 2; continue; }  // no length
    if (m >= 0xc0 && m <= 0xcf && m != 0xc4 && m != 0xc8 && m != 0xcc) return std::make_pair(be(i + 7, 2), be(i + 5, 2));
    i += 2 + be(i + 2, 2);
  }
  return std::nullopt;
}

// The largest texture side this loader takes: 16384 texels (a 1 GiB RGBA image at most).
constexpr std::uint32_t kMaxImageSide = 16384;

// What tinygltf's image callback needs besides the image: the model being read, and a place to put the first
// error with its place (tinygltf would keep only the text).
struct ImageContext {
  const tg::Model* model;
  std::string file;
  std::optional<Error> error;
};

// tinygltf's image callback: WebP (EXT_texture_webp) through libwebp, PNG and JPEG through tinygltf's own
// stb_image loader. Without it a file with a WebP image failed to load at all, even one that offers a PNG
// beside it. tinygltf 2.7 hands over an image's buffer view without checking that it lies within its buffer,
// and stb_image allocates what a PNG or JPEG header asks (up to 2 GB) before it reads the pixels, so both
// are checked here first.
bool load_image(tg::Image* image, const int image_idx, std::string* err, std::string* warn, int req_width, int req_height,
                const unsigned char* bytes, int size, void* user_data) {
  auto* ctx = static_cast<ImageContext*>(user_data);
  auto refuse = [&](const std::string& where, const std::string& reason) {  // load_model returns ctx->error
    if (!ctx->error) ctx->error = Error{ctx->file, where, reason};
    return false;
  };
  if (image->bufferView >= 0) {
    // tinygltf checked the view's and its buffer's indices.
    const tg::BufferView& bv = ctx->model->bufferViews[image->bufferView];
    const std::size_t have = ctx->model->buffers[bv.buffer].data.size();
    if (bv.byteOffset > have || bv.byteLength > have - bv.byteOffset || bv.byteLength > 0x7fffffffu)
      return refuse(idx("bufferViews", image->bufferView),
                    "byte range [" + std::to_string(bv.byteOffset) + ", " + std::to_string(bv.byteOffset + bv.byteLength) +
                        ") of image " + std::to_string(image_idx) + " lies outside its buffer of " + std::to_string(have) + " bytes");
  }
  auto too_large = [&](std::uint32_t w, std::uint32_t h) {
    return refuse(idx("images", image_idx), "is " + std::to_string(w) + " x " + std::to_string(h) +
                                                " pixels; this loader takes textures up to " + std::to_string(kMaxImageSide) + " on a side");
  };
  const bool webp = size >= 12 && std::memcmp(bytes, "RIFF", 4) == 0 && std::memcmp(bytes + 8, "WEBP", 4) == 0;
  if (!webp) {
    if (auto wh = png_or_jpeg_size(bytes, size); wh && std::max(wh->first, wh->second) > kMaxImageSide)
      return too_large(wh->first, wh->second);
    if (tg::LoadImageData(image, image_idx, err, warn, req_width, req_height, bytes, size, nullptr)) return true;
    return refuse(idx("images", image_idx), "the image does not decode (corrupt, or not a PNG or JPEG stb_image reads)");
  }
  int w = 0, h = 0;
  if (WebPGetInfo(bytes, static_cast<std::size_t>(size), &w, &h) && w > 0 && h > 0 &&
      static_cast<std::uint32_t>(std::max(w, h)) > kMaxImageSide)
    return too_large(static_cast<std::uint32_t>(w), static_cast<std::uint32_t>(h));
  std::uint8_t* rgba = size > 0 ? WebPDecodeRGBA(bytes, static_cast<std::size_t>(size), &w, &h) : nullptr;
  if (!rgba || w <= 0 || h <= 0) {
    if (rgba) WebPFree(rgba);
    return refuse(idx("images", image_idx), "the WebP image does not decode (corrupt, or not a WebP libwebp " +
                                                std::to_string(WebPGetDecoderVersion() >> 16) + "." +
                                                std::to_string((WebPGetDecoderVersion() >> 8) & 0xff) + " reads)");
  }
  image->width = w;
  image->height = h;
  image->component = 4;
  image->bits = 8;
  image->pixel_type = TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE;
  image->image.assign(rgba, rgba + static_cast<std::size_t>(w) * static_cast<std::size_t>(h) * 4);
  WebPFree(rgba);
  return true;
}

// tinygltf's file callbacks, for the files a .gltf names (buffers, images), taking regular files only. Its own
// take a directory (a uri of "" or ".") for a file of 2^63 - 1 bytes and try to allocate that, and wait
// forever on a FIFO.
bool file_exists(const std::string& path, void*) {
  std::error_code ec;
  return std::filesystem::is_regular_file(path, ec);
}
bool read_whole_file(std::vector<unsigned char>* out, std::string* err, const std::string& path, void*) {
  std::error_code ec;
  const std::uintmax_t size = std::filesystem::is_regular_file(path, ec) ? std::filesystem::file_size(path, ec) : 0;
  std::ifstream in;
  if (!ec && size > 0) in.open(path, std::ios::binary);
  if (ec || size == 0 || !in) {
    if (err) *err += "cannot read " + path + " (not a file, or empty)\n";
    return false;
  }
  out->resize(size);
  if (!in.read(reinterpret_cast<char*>(out->data()), static_cast<std::streamsize>(size))) {
    if (err) *err += "cannot read " + path + "\n";
    return false;
  }
  return true;
}

// The image a texture shows: EXT_texture_webp's source where it names one (the texture's own source
// is then a fallback, or absent), else its source.
int texture_source(const tg::Texture& t) {
  if (auto it = t.extensions.find("EXT_texture_webp"); it != t.extensions.end() && it->second.IsObject() &&
                                                         it->second.Has("source") && it->second.Get("source").IsInt())
    return it->second.Get("source").Get<int>();
  return t.source;
}

struct Ctx {
  const tg::Model& m;
  std::string file;
  Error err(const std::string& where, const std::string& reason) const { return Error{file, where, reason}; }
};

int component_size(int ct) {
  switch (ct) {
    case TINYGLTF_COMPONENT_TYPE_BYTE:
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: return 1;
    case TINYGLTF_COMPONENT_TYPE_SHORT:
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: return 2;
    case TINYGLTF_COMPONENT_TYPE_INT:
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT:
    case TINYGLTF_COMPONENT_TYPE_FLOAT: return 4;
    default: return 0;
  }
}

int type_components(int type) {
  switch (type) {
    case TINYGLTF_TYPE_SCALAR: return 1;
    case TINYGLTF_TYPE_VEC2: return 2;
    case TINYGLTF_TYPE_VEC3: return 3;
    case TINYGLTF_TYPE_VEC4: return 4;
    case TINYGLTF_TYPE_MAT2: return 4;
    case TINYGLTF_TYPE_MAT3: return 9;
    case TINYGLTF_TYPE_MAT4: return 16;
    default: return 0;
  }
}

// The bytes of buffer view `vi`, checked against its buffer.
Result<std::pair<const unsigned char*, std::size_t>> view_bytes(const Ctx& c, int vi, const std::string& user) {
  const auto& m = c.m;
  if (vi < 0 || vi >= static_cast<int>(m.bufferViews.size()))
    return c.err(user, "buffer view " + std::to_string(vi) + " does not exist");
  const tg::BufferView& bv = m.bufferViews[vi];
  std::string bvw = idx("bufferViews", vi);
  if (bv.buffer < 0 || bv.buffer >= static_cast<int>(m.buffers.size()))
    return c.err(bvw + ".buffer", "buffer " + std::to_string(bv.buffer) + " does not exist");
  const auto& data = m.buffers[bv.buffer].data;
  if (bv.byteOffset > data.size() || bv.byteLength > data.size() - bv.byteOffset)
    return c.err(bvw, "byte range [" + std::to_string(bv.byteOffset) + ", " + std::to_string(bv.byteOffset + bv.byteLength) +
                          ") lies outside its buffer of " + std::to_string(data.size()) + " bytes");
  return std::make_pair(data.data() + bv.byteOffset, bv.byteLength);
}

// One component of type `ct` at `p` as a double (normalized integers mapped to [0,1] or [-1,1]).
double component(int ct, const unsigned char* p, bool norm) {
  switch (ct) {
    case TINYGLTF_COMPONENT_TYPE_FLOAT: { float f; std::memcpy(&f, p, 4); return f; }
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: return norm ? *p / 255.0 : *p;
    case TINYGLTF_COMPONENT_TYPE_BYTE: { double v = static_cast<signed char>(*p); return norm ? std::max(v / 127.0, -1.0) : v; }
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: { std::uint16_t s; std::memcpy(&s, p, 2); return norm ? s / 65535.0 : s; }
    case TINYGLTF_COMPONENT_TYPE_SHORT: { std::int16_t s; std::memcpy(&s, p, 2); return norm ? std::max(s / 32767.0, -1.0) : s; }
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT: { std::uint32_t s; std::memcpy(&s, p, 4); return s; }
    default: return 0.0;
  }
}

// Reads accessor `ai` as `want_components` values per element, converting every component to
// double (normalized integers mapped to [0,1] or [-1,1] when the accessor says so or `normalize`).
// `allowed` lists the accepted component types. Applies a sparse substitution. Checks every byte range.
Result<std::vector<double>> read_accessor(const Ctx& c, int ai, int want_type, std::initializer_list<int> allowed,
                                          bool force_normalize, const std::string& user) {
  const auto& m = c.m;
  if (ai < 0 || ai >= static_cast<int>(m.accessors.size()))
    return c.err(user, "accessor index " + std::to_string(ai) + " does not exist");
  const tg::Accessor& a = m.accessors[ai];
  std::string where = idx("accessors", ai);
  if (a.type != want_type)
    return c.err(where + ".type", "has " + std::to_string(type_components(a.type)) + " components, " + user +
                                      " needs " + std::to_string(type_components(want_type)));
  if (std::find(allowed.begin(), allowed.end(), a.componentType) == allowed.end())
    return c.err(where + ".componentType", "component type " + std::to_string(a.componentType) + " is not allowed for " + user);
  const int nc = type_components(a.type);
  const int cs = component_size(a.componentType);
  if (a.count == 0) return c.err(where + ".count", "accessor is empty");
  if (a.count > (1u << 26)) return c.err(where + ".count", "accessor is implausibly large");
  std::vector<double> out(a.count * nc, 0.0);
  const bool norm = a.normalized || force_normalize;
  // Matrices of 1- and 2-byte components have column padding; we only read float matrices.
  const std::size_t elem = static_cast<std::size_t>(nc) * cs;
  auto convert = [&](const unsigned char* e, std::size_t i, std::size_t slot) -> Status {
    for (int k = 0; k < nc; ++k) {
      double v = component(a.componentType, e + k * cs, norm);
      if (!std::isfinite(v)) return c.err(where, "element " + std::to_string(i) + " is not a finite number");
      out[slot * nc + k] = v;
    }
    return Ok{};
  };
  if (a.bufferView >= 0) {  // without one the elements are zeros (before a sparse substitution), as glTF says
    auto bytes = view_bytes(c, a.bufferView, where + ".bufferView");
    if (!bytes) return bytes.error();
    const tg::BufferView& bv = m.bufferViews[a.bufferView];
    const std::size_t stride = bv.byteStride ? bv.byteStride : elem;
    if (stride < elem)
      return c.err(idx("bufferViews", a.bufferView) + ".byteStride", "stride " + std::to_string(stride) + " is smaller than an element");
    const std::size_t need = a.byteOffset + stride * (a.count - 1) + elem;
    if (a.byteOffset > bytes->second || need > bytes->second)
      return c.err(where, "accessor needs " + std::to_string(need) + " bytes, its buffer view has " + std::to_string(bytes->second));
    for (std::size_t i = 0; i < a.count; ++i)
      if (auto s = convert(bytes->first + a.byteOffset + i * stride, i, i); !s) return s.error();
  }
  if (a.sparse.isSparse) {
    const auto& sp = a.sparse;
    const std::string sw = where + ".sparse";
    if (sp.count <= 0 || static_cast<std::size_t>(sp.count) > a.count)
      return c.err(sw + ".count", "must be from 1 to the accessor's count " + std::to_string(a.count) + " (got " +
                                      std::to_string(sp.count) + ")");
    const std::size_t n = static_cast<std::size_t>(sp.count);
    const int ict = sp.indices.componentType;
    if (ict != TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE && ict != TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT &&
        ict != TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT)
      return c.err(sw + ".indices.componentType", "component type " + std::to_string(ict) + " is not an unsigned integer type");
    auto ib = view_bytes(c, sp.indices.bufferView, sw + ".indices.bufferView");
    if (!ib) return ib.error();
    auto vb = view_bytes(c, sp.values.bufferView, sw + ".values.bufferView");
    if (!vb) return vb.error();
    const std::size_t ics = component_size(ict);
    const std::size_t ioff = static_cast<std::size_t>(std::max(sp.indices.byteOffset, 0));
    const std::size_t voff = static_cast<std::size_t>(std::max(sp.values.byteOffset, 0));
    if (ioff > ib->second || n * ics > ib->second - ioff)
      return c.err(sw + ".indices", std::to_string(n) + " indices need " + std::to_string(ioff + n * ics) +
                                        " bytes, the buffer view has " + std::to_string(ib->second));
    if (voff > vb->second || n * elem > vb->second - voff)
      return c.err(sw + ".values", std::to_string(n) + " values need " + std::to_string(voff + n * elem) +
                                       " bytes, the buffer view has " + std::to_string(vb->second));
    double previous = -1.0;
    for (std::size_t s = 0; s < n; ++s) {
      const double target = component(ict, ib->first + ioff + s * ics, false);
      if (!(target > previous))
        return c.err(sw + ".indices", "index " + std::to_string(s) + " does not increase strictly");
      if (target >= static_cast<double>(a.count))
        return c.err(sw + ".indices", "index " + std::to_string(static_cast<long long>(target)) + " is past the " +
                                          std::to_string(a.count) + " elements");
      previous = target;
      if (auto st = convert(vb->first + voff + s * elem, static_cast<std::size_t>(target), static_cast<std::size_t>(target)); !st)
        return st.error();
    }
  }
  return out;
}

constexpr int kF = TINYGLTF_COMPONENT_TYPE_FLOAT;
constexpr int kUB = TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE;
constexpr int kUS = TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT;
constexpr int kUI = TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT;
constexpr int kB = TINYGLTF_COMPONENT_TYPE_BYTE;
constexpr int kS = TINYGLTF_COMPONENT_TYPE_SHORT;

// A triangle strip's or fan's indices as a triangle list, in glTF's order (a strip's odd triangles
// swap their first two corners, so every triangle keeps the strip's winding); triangles with a
// repeated corner (the degenerate ones that join strips) are dropped.
std::vector<std::uint32_t> triangle_list(const std::vector<std::uint32_t>& in, bool fan) {
  std::vector<std::uint32_t> out;
  if (in.size() < 3) return out;
  out.reserve(3 * (in.size() - 2));
  for (std::size_t i = 0; i + 2 < in.size(); ++i) {
    std::uint32_t a = fan ? in[i + 1] : in[i], b = fan ? in[i + 2] : in[i + 1], c = fan ? in[0] : in[i + 2];
    if (!fan && i % 2 == 1) std::swap(a, b);
    if (a == b || b == c || a == c) continue;
    out.insert(out.end(), {a, b, c});
  }
  return out;
}

bool finite_all(const std::vector<double>& v) {
  return std::all_of(v.begin(), v.end(), [](double x) { return std::isfinite(x); });
}

Result<Transform> node_local(const Ctx& c, int ni) {
  const tg::Node& n = c.m.nodes[ni];
  std::string w = idx("nodes", ni);
  Transform t;
  if (!n.matrix.empty()) {
    if (n.matrix.size() != 16 || !finite_all(n.matrix)) return c.err(w + ".matrix", "needs 16 finite numbers");
    glm::mat4 m;
    for (int i = 0; i < 16; ++i) glm::value_ptr(m)[i] = static_cast<float>(n.matrix[i]);
    glm::vec3 skew;
    glm::vec4 persp;
    if (!glm::decompose(m, t.scale, t.rotation, t.translation, skew, persp))
      return c.err(w + ".matrix", "is not a translation-rotation-scale transform");
    t.rotation = glm::normalize(t.rotation);
    return t;
  }
  if (!n.translation.empty()) {
    if (n.translation.size() != 3 || !finite_all(n.translation)) return c.err(w + ".translation", "needs 3 finite numbers");
    t.translation = glm::vec3(n.translation[0], n.translation[1], n.translation[2]);
  }
  if (!n.rotation.empty()) {
    if (n.rotation.size() != 4 || !finite_all(n.rotation)) return c.err(w + ".rotation", "needs 4 finite numbers");
    glm::quat q(static_cast<float>(n.rotation[3]), static_cast<float>(n.rotation[0]), static_cast<float>(n.rotation[1]),
                static_cast<float>(n.rotation[2]));
    float l = glm::length(q);
    if (!(l > 1e-6f)) return c.err(w + ".rotation", "is not a rotation (zero quaternion)");
    t.rotation = q / l;
  }
  if (!n.scale.empty()) {
    if (n.scale.size() != 3 || !finite_all(n.scale)) return c.err(w + ".scale", "needs 3 finite numbers");
    t.scale = glm::vec3(n.scale[0], n.scale[1], n.scale[2]);
  }
  return t;
}

std::vector<double> number_array(const tg::Value& v) {
  std::vector<double> r;
  if (!v.IsArray()) return r;
  for (std::size_t i = 0; i < v.ArrayLen(); ++i)
    if (v.Get(static_cast<int>(i)).IsNumber()) r.push_back(v.Get(static_cast<int>(i)).GetNumberAsDouble());
  return r;
}

// The texture coordinate set a material's base colour texture reads, and its KHR_texture_transform.
struct UvSet {
  int set = 0;
  glm::mat3 transform{1.0f};
};

struct Builder {
  const Ctx& c;
  Model& out;
  bool quantized = false;  // KHR_mesh_quantization is used
  std::vector<int> remap;  // glTF node -> runtime node
  std::map<int, int> skin_offset, rigid_slot, image_texture;
  std::map<std::pair<int, bool>, int> material_index;  // (glTF material, vertex colours) -> runtime material
  int default_material[2] = {-1, -1};
  std::vector<TextureSampler> sampler_table;  // per glTF sampler

  // Reads every glTF sampler and checks every texture's reference to one.
  Status samplers() {
    for (std::size_t i = 0; i < c.m.samplers.size(); ++i) {
      const tg::Sampler& gs = c.m.samplers[i];
      const std::string sw = idx("samplers", static_cast<int>(i));
      TextureSampler ts;
      auto wrap = [&](int v, const char* key, Wrap& w) -> Status {
        switch (v) {
          case 10497: w = Wrap::kRepeat; return Ok{};
          case 33071: w = Wrap::kClampToEdge; return Ok{};
          case 33648: w = Wrap::kMirroredRepeat; return Ok{};
          default:
            return c.err(sw + "." + key, std::to_string(v) + " is not a wrap mode (10497 REPEAT, 33071 CLAMP_TO_EDGE, 33648 MIRRORED_REPEAT)");
        }
      };
      if (auto s = wrap(gs.wrapS, "wrapS", ts.wrap_s); !s) return s;
      if (auto s = wrap(gs.wrapT, "wrapT", ts.wrap_t); !s) return s;
      if (gs.magFilter != -1 && gs.magFilter != 9728 && gs.magFilter != 9729)
        return c.err(sw + ".magFilter", std::to_string(gs.magFilter) + " is not a magnification filter (9728 NEAREST, 9729 LINEAR)");
      ts.mag_nearest = gs.magFilter == 9728;
      switch (gs.minFilter) {
        case -1: break;  // not given: trilinear
        case 9728: ts.min_nearest = true, ts.mipmaps = false; break;                  // NEAREST
        case 9729: ts.mipmaps = false; break;                                          // LINEAR
        case 9984: ts.min_nearest = true, ts.mip_nearest = true; break;                // NEAREST_MIPMAP_NEAREST
        case 9985: ts.mip_nearest = true; break;                                       // LINEAR_MIPMAP_NEAREST
        case 9986: ts.min_nearest = true; break;                                       // NEAREST_MIPMAP_LINEAR
        case 9987: break;                                                              // LINEAR_MIPMAP_LINEAR
        default:
          return c.err(sw + ".minFilter", std::to_string(gs.minFilter) + " is not a minification filter (9728, 9729, 9984 to 9987)");
      }
      sampler_table.push_back(ts);
    }
    for (std::size_t i = 0; i < c.m.textures.size(); ++i) {
      const int s = c.m.textures[i].sampler;
      if (s < -1 || s >= static_cast<int>(sampler_table.size()))
        return c.err(idx("textures", static_cast<int>(i)) + ".sampler", "sampler " + std::to_string(s) + " does not exist");
    }
    return Ok{};
  }

  UvSet uv_set(int mi) const {
    UvSet r;
    if (mi < 0 || mi >= static_cast<int>(c.m.materials.size())) return r;
    const tg::TextureInfo& ti = c.m.materials[mi].pbrMetallicRoughness.baseColorTexture;
    r.set = std::clamp(ti.texCoord, 0, 7);
    auto it = ti.extensions.find("KHR_texture_transform");
    if (it == ti.extensions.end() || !it->second.IsObject()) return r;
    const tg::Value& x = it->second;
    auto pair = [&](const char* key, glm::vec2 fallback) {
      std::vector<double> v = number_array(x.Get(key));
      return v.size() == 2 && finite_all(v) ? glm::vec2(v[0], v[1]) : fallback;
    };
    const glm::vec2 offset = pair("offset", glm::vec2(0.0f)), scale = pair("scale", glm::vec2(1.0f));
    float rotation = 0.0f;
    if (x.Get("rotation").IsNumber() && std::isfinite(x.Get("rotation").GetNumberAsDouble()))
      rotation = static_cast<float>(x.Get("rotation").GetNumberAsDouble());
    if (x.Get("texCoord").IsNumber())  // clamped before the conversion, which 1e30 would overflow
      r.set = static_cast<int>(std::clamp(x.Get("texCoord").GetNumberAsDouble(), 0.0, 7.0));
    // translation * rotation * scale, column-major as the extension's GLSL.
    const glm::mat3 t(1, 0, 0, 0, 1, 0, offset.x, offset.y, 1);
    const glm::mat3 rot(std::cos(rotation), std::sin(rotation), 0, -std::sin(rotation), std::cos(rotation), 0, 0, 0, 1);
    const glm::mat3 sc(scale.x, 0, 0, 0, scale.y, 0, 0, 0, 1);
    r.transform = t * rot * sc;
    return r;
  }

  Status hierarchy() {
    const auto& nodes = c.m.nodes;
    const int n = static_cast<int>(nodes.size());
    std::vector<int> parent(n, -1);
    for (int i = 0; i < n; ++i)
      for (std::size_t k = 0; k < nodes[i].children.size(); ++k) {
        int ch = nodes[i].children[k];
        std::string w = idx("nodes", i) + ".children[" + std::to_string(k) + "]";
        if (ch < 0 || ch >= n) return c.err(w, "node " + std::to_string(ch) + " does not exist");
        if (ch == i) return c.err(w, "a node cannot be its own child");
        if (parent[ch] >= 0) return c.err(w, "node " + std::to_string(ch) + " has more than one parent");
        parent[ch] = i;
      }
    remap.assign(n, -1);
    std::vector<int> stack;
    for (int r = 0; r < n; ++r) {
      if (parent[r] >= 0) continue;
      stack.push_back(r);
      while (!stack.empty()) {
        int g = stack.back();
        stack.pop_back();
        remap[g] = static_cast<int>(out.nodes.size());
        Node node;
        node.name = nodes[g].name;
        node.parent = parent[g] >= 0 ? remap[parent[g]] : -1;
        auto local = node_local(c, g);
        if (!local) return local.error();
        node.rest = *local;
        out.nodes.push_back(std::move(node));
        for (auto it = nodes[g].children.rbegin(); it != nodes[g].children.rend(); ++it) stack.push_back(*it);
      }
    }
    for (int i = 0; i < n; ++i)
      if (remap[i] < 0) return c.err(idx("nodes", i), "the node hierarchy has a loop");
    return Ok{};
  }

  Result<int> skin_palette(int si) {
    if (auto it = skin_offset.find(si); it != skin_offset.end()) return it->second;
    const tg::Skin& s = c.m.skins[si];
    std::string w = idx("skins", si);
    if (s.joints.empty()) return c.err(w + ".joints", "skin has no joints");
    std::vector<double> ibm;
    if (s.inverseBindMatrices >= 0) {
      auto r = read_accessor(c, s.inverseBindMatrices, TINYGLTF_TYPE_MAT4, {kF}, false, w + ".inverseBindMatrices");
      if (!r) return r.error();
      ibm = std::move(*r);
      if (ibm.size() / 16 < s.joints.size())
        return c.err(w + ".inverseBindMatrices", "has " + std::to_string(ibm.size() / 16) + " matrices for " +
                                                     std::to_string(s.joints.size()) + " joints");
    }
    int offset = static_cast<int>(out.palette.size());
    for (std::size_t j = 0; j < s.joints.size(); ++j) {
      int jn = s.joints[j];
      if (jn < 0 || jn >= static_cast<int>(remap.size()))
        return c.err(w + ".joints[" + std::to_string(j) + "]", "node " + std::to_string(jn) + " does not exist");
      PaletteEntry e;
      e.node = remap[jn];
      if (!ibm.empty())
        for (int k = 0; k < 16; ++k) glm::value_ptr(e.inverse_bind)[k] = static_cast<float>(ibm[j * 16 + k]);
      out.palette.push_back(e);
    }
    if (out.palette.size() > 65535) return c.err(w, "more than 65535 skinning matrices");
    skin_offset[si] = offset;
    return offset;
  }

  // Whether runtime node `n`'s rest transform in the world mirrors (an odd number of negative
  // scales along its chain).
  bool mirrored(int n) const {
    bool odd = false;
    for (; n >= 0; n = out.nodes[static_cast<std::size_t>(n)].parent) {
      const glm::vec3 s = out.nodes[static_cast<std::size_t>(n)].rest.scale;
      odd ^= s.x * s.y * s.z < 0.0f;
    }
    return odd;
  }

  int rigid(int runtime_node) {
    if (auto it = rigid_slot.find(runtime_node); it != rigid_slot.end()) return it->second;
    int slot = static_cast<int>(out.palette.size());
    out.palette.push_back(PaletteEntry{runtime_node, glm::mat4(1.0f)});
    rigid_slot[runtime_node] = slot;
    return slot;
  }

  int texture_for_image(int image) {
    if (auto it = image_texture.find(image); it != image_texture.end()) return it->second;
    int result = -1;
    if (image >= 0 && image < static_cast<int>(c.m.images.size())) {
      const tg::Image& im = c.m.images[image];
      const std::size_t px = static_cast<std::size_t>(std::max(im.width, 0)) * std::max(im.height, 0);
      const int comp = im.component, bytes = im.bits == 16 ? 2 : 1;
      if (px > 0 && comp >= 1 && comp <= 4 && (im.bits == 8 || im.bits == 16) &&
          im.image.size() >= px * comp * bytes) {
        Texture t;
        t.width = im.width;
        t.height = im.height;
        t.rgba.resize(px * 4);
        for (std::size_t p = 0; p < px; ++p) {
          unsigned char ch[4] = {0, 0, 0, 255};
          for (int k = 0; k < comp; ++k) ch[k] = im.image[(p * comp + k) * bytes + (bytes - 1)];  // high byte
          if (comp == 1 || comp == 2) {  // grey (+ alpha)
            ch[3] = comp == 2 ? ch[1] : 255;
            ch[1] = ch[2] = ch[0];
          }
          std::memcpy(&t.rgba[p * 4], ch, 4);
        }
        result = static_cast<int>(out.textures.size());
        out.textures.push_back(std::move(t));
      }
    }
    image_texture[image] = result;
    return result;
  }

  // The runtime material for glTF material `mi` on a primitive with (`colored`) or without vertex colours.
  int material(int mi, bool colored) {
    if (mi < 0 || mi >= static_cast<int>(c.m.materials.size())) {
      if (default_material[colored] < 0) {
        default_material[colored] = static_cast<int>(out.materials.size());
        Material mat{glm::vec4(1.0f)};  // glTF's default material: white, lit
        mat.vertex_colors = colored;
        out.materials.push_back(mat);
      }
      return default_material[colored];
    }
    if (auto it = material_index.find({mi, colored}); it != material_index.end()) return it->second;
    const tg::Material& gm = c.m.materials[mi];
    Material mat;
    mat.vertex_colors = colored;
    const auto& f = gm.pbrMetallicRoughness.baseColorFactor;
    if (f.size() == 4 && finite_all(f)) mat.base_color = glm::vec4(f[0], f[1], f[2], f[3]);
    int ti = gm.pbrMetallicRoughness.baseColorTexture.index;
    if (ti >= 0 && ti < static_cast<int>(c.m.textures.size())) {
      mat.texture = texture_for_image(texture_source(c.m.textures[ti]));
      if (const int si = c.m.textures[ti].sampler; si >= 0) mat.sampler = sampler_table[si];
    }
    mat.unlit = gm.extensions.count("KHR_materials_unlit") > 0;
    if (const auto& e = gm.emissiveFactor; e.size() == 3 && finite_all(e))
      mat.emissive = glm::clamp(glm::vec3(e[0], e[1], e[2]), glm::vec3(0.0f), glm::vec3(1.0f));
    if (gm.alphaMode == "MASK") {
      mat.alpha_mask = true;
      mat.alpha_cutoff = static_cast<float>(gm.alphaCutoff);
    }
    mat.alpha_blend = gm.alphaMode == "BLEND";
    mat.double_sided = gm.doubleSided;
    int r = static_cast<int>(out.materials.size());
    out.materials.push_back(mat);
    material_index[{mi, colored}] = r;
    return r;
  }

  // Morph targets: adds each target's POSITION (and NORMAL, where the primitive has normals) displacements
  // times its default weight (node `gn`'s weights, else mesh `mi`'s; none: all 0) to `pos` and `nrm`.
  Status bake_morph_targets(const tg::Primitive& p, const std::string& pw, int gn, int mi, std::size_t nv,
                            std::vector<double>& pos, std::vector<double>& nrm) {
    const tg::Node& node = c.m.nodes[gn];
    const tg::Mesh& mesh = c.m.meshes[mi];
    const bool own = !node.weights.empty();
    const std::vector<double>& w = own ? node.weights : mesh.weights;
    const std::string ww = own ? idx("nodes", gn) + ".weights" : idx("meshes", mi) + ".weights";
    if (!w.empty() && w.size() != p.targets.size())
      return c.err(ww, "has " + std::to_string(w.size()) + " weights, " + pw + " has " + std::to_string(p.targets.size()) + " targets");
    MorphReport& rep = out.morph_report;
    ++rep.primitives;
    rep.most_targets = std::max(rep.most_targets, static_cast<int>(p.targets.size()));
    bool moved_normals = false;
    for (std::size_t t = 0; t < p.targets.size(); ++t) {
      const double wt = t < w.size() ? w[t] : 0.0;
      const std::string tw = pw + ".targets[" + std::to_string(t) + "]";
      if (!std::isfinite(wt)) return c.err(ww, "weight " + std::to_string(t) + " is not finite");
      for (const auto& [name, ai] : p.targets[t]) {
        const bool is_pos = name == "POSITION", is_nrm = name == "NORMAL";
        if (wt == 0.0 || !(is_pos || (is_nrm && !nrm.empty()))) continue;  // TANGENT, TEXCOORD_n, COLOR_n: not drawn
        auto d = read_accessor(c, ai, TINYGLTF_TYPE_VEC3, {kF, kB, kS}, false, tw + "." + name);
        if (!d) return d.error();
        if (d->size() / 3 != nv)
          return c.err(tw + "." + name, "has " + std::to_string(d->size() / 3) + " elements, POSITION has " + std::to_string(nv));
        std::vector<double>& dst = is_pos ? pos : nrm;
        for (std::size_t k = 0; k < dst.size(); ++k) dst[k] += wt * (*d)[k];
        moved_normals |= is_nrm;
      }
      rep.weighted_targets += wt != 0.0;
    }
    if (moved_normals)
      for (std::size_t v = 0; v < nv; ++v) {
        const double l = std::sqrt(nrm[3 * v] * nrm[3 * v] + nrm[3 * v + 1] * nrm[3 * v + 1] + nrm[3 * v + 2] * nrm[3 * v + 2]);
        if (l > 0.0)
          for (int k = 0; k < 3; ++k) nrm[3 * v + k] /= l;
      }
    return Ok{};
  }

  // Appends mesh `mi` drawn by glTF node `gn` to `lod`.
  Status add_mesh(MeshLod& lod, int gn, int mi, int si) {
    std::string mw = idx("meshes", mi);
    if (mi < 0 || mi >= static_cast<int>(c.m.meshes.size()))
      return c.err(idx("nodes", gn) + ".mesh", "mesh " + std::to_string(mi) + " does not exist");
    int palette_offset = 0, slot = 0;
    bool skinned = si >= 0;
    if (skinned) {
      if (si >= static_cast<int>(c.m.skins.size()))
        return c.err(idx("nodes", gn) + ".skin", "skin " + std::to_string(si) + " does not exist");
      auto off = skin_palette(si);
      if (!off) return off.error();
      palette_offset = *off;
    } else {
      slot = rigid(remap[gn]);
    }
    const int joint_count = skinned ? static_cast<int>(c.m.skins[si].joints.size()) : 1;
    const auto& prims = c.m.meshes[mi].primitives;
    for (std::size_t pi = 0; pi < prims.size(); ++pi) {
      const tg::Primitive& p = prims[pi];
      std::string pw = mw + ".primitives[" + std::to_string(pi) + "]";
      // Points and lines are not a skin; strips and fans are triangles and become a list (below).
      const bool strip = p.mode == TINYGLTF_MODE_TRIANGLE_STRIP, fan = p.mode == TINYGLTF_MODE_TRIANGLE_FAN;
      if (p.mode != -1 && p.mode != TINYGLTF_MODE_TRIANGLES && !strip && !fan) continue;
      auto attr = [&](const char* name) { auto it = p.attributes.find(name); return it == p.attributes.end() ? -1 : it->second; };
      int ap = attr("POSITION");
      if (ap < 0) return c.err(pw + ".attributes", "has no POSITION");
      // KHR_mesh_quantization: integer positions (the node or the inverse bind matrices scale them back),
      // normalized integer normals, integer texture coordinates.
      auto pos = read_accessor(c, ap, TINYGLTF_TYPE_VEC3, {kF, kB, kUB, kS, kUS}, false, pw + ".attributes.POSITION");
      if (!pos) return pos.error();
      std::size_t nv = pos->size() / 3;
      auto same_count = [&](const std::vector<double>& v, int comps, const char* what) -> Status {
        if (v.size() / comps != nv)
          return c.err(pw + ".attributes." + what, "has " + std::to_string(v.size() / comps) + " elements, POSITION has " + std::to_string(nv));
        return Ok{};
      };
      std::vector<double> nrm, uv, jnt, wgt;
      if (int a = attr("NORMAL"); a >= 0) {
        auto r = read_accessor(c, a, TINYGLTF_TYPE_VEC3, {kF, kB, kS}, true, pw + ".attributes.NORMAL");
        if (!r) return r.error();
        nrm = std::move(*r);
        if (auto s = same_count(nrm, 3, "NORMAL"); !s) return s;
      }
      const UvSet uvset = uv_set(p.material);
      const std::string uv_name = "TEXCOORD_" + std::to_string(uvset.set);
      if (int a = attr(uv_name.c_str()); a >= 0) {
        // Core glTF has normalized unsigned texture coordinates only; with quantization the flag decides.
        auto r = read_accessor(c, a, TINYGLTF_TYPE_VEC2, {kF, kB, kUB, kS, kUS}, !quantized, pw + ".attributes." + uv_name);
        if (!r) return r.error();
        uv = std::move(*r);
        if (auto s = same_count(uv, 2, uv_name.c_str()); !s) return s;
        for (std::size_t v = 0; v < uv.size(); v += 2) {
          glm::vec2 t = uvset.transform * glm::vec3(uv[v], uv[v + 1], 1.0);
          uv[v] = t.x, uv[v + 1] = t.y;
        }
      }
      if (!p.targets.empty()) {
        if (auto s = bake_morph_targets(p, pw, gn, mi, nv, *pos, nrm); !s) return s;
      }
      std::vector<double> col;  // COLOR_0 as RGBA
      if (int a = attr("COLOR_0"); a >= 0) {
        const bool rgb = a < static_cast<int>(c.m.accessors.size()) && c.m.accessors[a].type == TINYGLTF_TYPE_VEC3;
        auto r = read_accessor(c, a, rgb ? TINYGLTF_TYPE_VEC3 : TINYGLTF_TYPE_VEC4, {kF, kUB, kUS}, true, pw + ".attributes.COLOR_0");
        if (!r) return r.error();
        if (auto s = same_count(*r, rgb ? 3 : 4, "COLOR_0"); !s) return s;
        col.resize(nv * 4, 1.0);
        for (std::size_t v = 0; v < nv; ++v)
          for (int k = 0; k < (rgb ? 3 : 4); ++k) col[4 * v + k] = (*r)[v * (rgb ? 3 : 4) + k];
      }
      int sets = 0;  // JOINTS_n / WEIGHTS_n pairs read
      double weight_tolerance = 1e-5;
      if (skinned) {
        for (int set = 0; set < 2; ++set) {
          const std::string jn = "JOINTS_" + std::to_string(set), wn = "WEIGHTS_" + std::to_string(set);
          int aj = attr(jn.c_str()), aw = attr(wn.c_str());
          if (set > 0 && (aj < 0 || aw < 0)) break;
          if (aj < 0 || aw < 0) return c.err(pw + ".attributes", "a skinned mesh needs JOINTS_0 and WEIGHTS_0");
          auto rj = read_accessor(c, aj, TINYGLTF_TYPE_VEC4, {kUB, kUS}, false, pw + ".attributes." + jn);
          if (!rj) return rj.error();
          auto rw = read_accessor(c, aw, TINYGLTF_TYPE_VEC4, {kF, kUB, kUS}, true, pw + ".attributes." + wn);
          if (!rw) return rw.error();
          if (auto s = same_count(*rj, 4, jn.c_str()); !s) return s;
          if (auto s = same_count(*rw, 4, wn.c_str()); !s) return s;
          jnt.insert(jnt.end(), rj->begin(), rj->end());
          wgt.insert(wgt.end(), rw->begin(), rw->end());
          // What "sums to 1" can mean for weights stored this way (the validator's tolerance).
          if (c.m.accessors[aw].componentType != kF) weight_tolerance = std::max(weight_tolerance, 2.0 / 255.0);
          ++sets;
        }
        out.skin_report.skin_joints = std::max(out.skin_report.skin_joints, joint_count);
      }
      std::vector<std::uint32_t> ind;
      if (p.indices >= 0) {
        auto r = read_accessor(c, p.indices, TINYGLTF_TYPE_SCALAR, {kUB, kUS, kUI}, false, pw + ".indices");
        if (!r) return r.error();
        ind.reserve(r->size());
        for (std::size_t k = 0; k < r->size(); ++k) {
          double v = (*r)[k];
          if (v >= static_cast<double>(nv))
            return c.err(idx("accessors", p.indices), "index " + std::to_string(static_cast<long long>(v)) + " at element " +
                                                          std::to_string(k) + " is past the " + std::to_string(nv) + " vertices");
          ind.push_back(static_cast<std::uint32_t>(v));
        }
      } else {
        ind.resize(nv);
        for (std::size_t k = 0; k < nv; ++k) ind[k] = static_cast<std::uint32_t>(k);
      }
      if (strip || fan) ind = triangle_list(ind, fan);
      ind.resize(ind.size() / 3 * 3);
      if (ind.empty()) continue;
      if (nrm.empty() && (p.indices >= 0 || strip || fan)) {
        // glTF: without normals a client computes flat ones, so every corner gets a vertex of its own.
        auto corners = [&](std::vector<double>& a, std::size_t comps, int sets_of) {
          std::vector<double> b(ind.size() * comps * sets_of);
          for (int st = 0; st < sets_of; ++st)
            for (std::size_t k = 0; k < ind.size(); ++k)
              for (std::size_t e = 0; e < comps; ++e)
                b[(st * ind.size() + k) * comps + e] = a[(st * nv + ind[k]) * comps + e];
          a = std::move(b);
        };
        corners(*pos, 3, 1);
        if (!uv.empty()) corners(uv, 2, 1);
        if (!col.empty()) corners(col, 4, 1);
        if (skinned) corners(jnt, 4, sets), corners(wgt, 4, sets);
        nv = ind.size();
        for (std::size_t k = 0; k < ind.size(); ++k) ind[k] = static_cast<std::uint32_t>(k);
      }
      const std::uint32_t base = static_cast<std::uint32_t>(lod.vertices.size());
      for (std::size_t v = 0; v < nv; ++v) {
        Vertex vx;
        vx.position = glm::vec3(pos->at(3 * v), pos->at(3 * v + 1), pos->at(3 * v + 2));
        if (!nrm.empty()) vx.normal = glm::vec3(nrm[3 * v], nrm[3 * v + 1], nrm[3 * v + 2]);
        if (!uv.empty()) vx.uv = glm::vec2(uv[2 * v], uv[2 * v + 1]);
        if (!col.empty())
          for (int k = 0; k < 4; ++k)
            vx.color[k] = static_cast<std::uint8_t>(std::lround(std::clamp(col[4 * v + k], 0.0, 1.0) * 255.0));
        if (skinned) {
          // Up to eight influences (JOINTS_0 and JOINTS_1); the four heaviest are kept.
          std::pair<double, int> inf[8];
          const int n_inf = 4 * sets;
          double stored = 0.0, total = 0.0;  // the sums of the weights as stored and of the kept-valid ones
          int nonzero = 0;
          for (int k = 0; k < n_inf; ++k) {
            const std::size_t at = static_cast<std::size_t>(k / 4) * nv * 4 + 4 * v + k % 4;
            double j = jnt[at];
            double wk = std::max(0.0, wgt[at]);
            if (wk > 0.0 && j >= joint_count)
              return c.err(pw + ".attributes.JOINTS_" + std::to_string(k / 4),
                           "vertex " + std::to_string(v) + " uses joint " + std::to_string(static_cast<long long>(j)) +
                               " of a skin with " + std::to_string(joint_count));
            if (j >= joint_count) wk = 0.0, j = 0;
            inf[k] = {wk, static_cast<int>(j)};
            stored += wgt[at];
            total += wk;
            nonzero += wk > 0.0;
          }
          if (n_inf > 4)  // stable: equal weights keep their order
            std::stable_sort(inf, inf + n_inf, [](const auto& a, const auto& b) { return a.first > b.first; });
          SkinReport& rep = out.skin_report;
          ++rep.skinned_vertices;
          rep.max_influences = std::max(rep.max_influences, nonzero);
          rep.worst_weight_sum_error = std::max(rep.worst_weight_sum_error, std::abs(stored - 1.0));
          if (std::abs(stored - 1.0) > weight_tolerance) rep.weights_normalized = false;
          if (nonzero > 4) {
            ++rep.vertices_over_four;
            double dropped = 0.0;
            for (int k = 4; k < n_inf; ++k) dropped += inf[k].first;
            rep.worst_dropped_weight = std::max(rep.worst_dropped_weight, total > 0.0 ? dropped / total : 0.0);
          }
          glm::vec4 w(0.0f);
          for (int k = 0; k < 4; ++k) {
            vx.joints[k] = static_cast<std::uint16_t>(palette_offset + inf[k].second);
            w[k] = static_cast<float>(inf[k].first);
          }
          float sum = w.x + w.y + w.z + w.w;
          if (sum > 0.0f) {
            vx.weights = w / sum;
          } else {
            vx.weights = glm::vec4(1, 0, 0, 0);
          }
        } else {
          vx.joints = glm::u16vec4(static_cast<std::uint16_t>(slot));
          vx.weights = glm::vec4(1, 0, 0, 0);
        }
        lod.vertices.push_back(vx);
      }
      if (nrm.empty()) {  // flat normals: every corner has its own vertex (above)
        std::vector<glm::vec3> acc(nv, glm::vec3(0.0f));
        for (std::size_t t = 0; t < ind.size(); t += 3) {
          glm::vec3 a = lod.vertices[base + ind[t]].position, b = lod.vertices[base + ind[t + 1]].position,
                    d = lod.vertices[base + ind[t + 2]].position;
          glm::vec3 fnrm = glm::cross(b - a, d - a);
          for (int k = 0; k < 3; ++k) acc[ind[t + k]] += fnrm;
        }
        for (std::size_t v = 0; v < nv; ++v) {
          float l = glm::length(acc[v]);
          lod.vertices[base + v].normal = l > 0.0f ? acc[v] / l : glm::vec3(0, 1, 0);
        }
      }
      // A rigid mesh under a mirroring node (a negative determinant of its rest transform, glTF's
      // rule for the winding) has its triangles turned, so that front faces wind counter-clockwise
      // as drawn (Material::double_sided). A skinned mesh keeps the file's winding.
      if (!skinned && mirrored(remap[gn]))
        for (std::size_t t = 0; t + 2 < ind.size(); t += 3) std::swap(ind[t + 1], ind[t + 2]);
      Primitive prim;
      prim.first_index = static_cast<std::uint32_t>(lod.indices.size());
      prim.index_count = static_cast<std::uint32_t>(ind.size());
      prim.material = material(p.material, !col.empty());
      for (auto i : ind) lod.indices.push_back(base + i);
      lod.primitives.push_back(prim);
    }
    return Ok{};
  }

  Status meshes() {
    const auto& m = c.m;
    // Mesh nodes reachable from the scene (its roots; every root node without scenes).
    std::vector<int> roots;
    int scene = m.defaultScene >= 0 ? m.defaultScene : (m.scenes.empty() ? -1 : 0);
    if (scene >= static_cast<int>(m.scenes.size())) return c.err("$.scene", "scene " + std::to_string(scene) + " does not exist");
    if (scene >= 0) {
      for (std::size_t k = 0; k < m.scenes[scene].nodes.size(); ++k) {
        int r = m.scenes[scene].nodes[k];
        if (r < 0 || r >= static_cast<int>(m.nodes.size()))
          return c.err(idx("scenes", scene) + ".nodes[" + std::to_string(k) + "]", "node " + std::to_string(r) + " does not exist");
        roots.push_back(r);
      }
    } else {
      std::vector<bool> child(m.nodes.size(), false);
      for (const auto& n : m.nodes)
        for (int ch : n.children) child[ch] = true;
      for (std::size_t i = 0; i < m.nodes.size(); ++i)
        if (!child[i]) roots.push_back(static_cast<int>(i));
    }
    struct Base { int node; std::vector<int> lod_nodes; std::vector<double> coverage; };
    std::vector<Base> bases;
    std::vector<int> stack(roots.rbegin(), roots.rend());
    std::vector<bool> seen(m.nodes.size(), false);
    while (!stack.empty()) {
      int g = stack.back();
      stack.pop_back();
      if (seen[g]) continue;
      seen[g] = true;
      const tg::Node& n = m.nodes[g];
      if (n.mesh >= 0) {
        Base b{g, {}, {}};
        if (auto it = n.extensions.find("MSFT_lod"); it != n.extensions.end()) {
          const tg::Value& ids = it->second.Get("ids");
          std::vector<double> v = number_array(ids);
          for (std::size_t k = 0; k < v.size(); ++k) {
            // (Range first: converting 1e30 to int is undefined.)
            const bool node = v[k] >= 0 && v[k] < static_cast<double>(m.nodes.size()) && v[k] == std::floor(v[k]);
            const int id = node ? static_cast<int>(v[k]) : -1;
            if (!node || m.nodes[id].mesh < 0)
              return c.err(idx("nodes", g) + ".extensions.MSFT_lod.ids[" + std::to_string(k) + "]",
                           "is not a node with a mesh");
            b.lod_nodes.push_back(id);
          }
          if (n.extras.Has("MSFT_screencoverage")) b.coverage = number_array(n.extras.Get("MSFT_screencoverage"));
        }
        bases.push_back(std::move(b));
      }
      for (auto it = n.children.rbegin(); it != n.children.rend(); ++it) stack.push_back(*it);
    }
    if (bases.empty()) return c.err("$.nodes", "the scene has no mesh");
    // A skinned node's joints must be in its scene (the validator's NODE_SKIN_NO_SCENE): their
    // transforms are the scene's, so a skeleton outside it has no place to be drawn from.
    if (scene >= 0)
      for (const auto& b : bases)
        for (std::size_t l = 0; l <= b.lod_nodes.size(); ++l) {
          const int gn = l == 0 ? b.node : b.lod_nodes[l - 1];
          const int skin = m.nodes[gn].skin;
          if (skin < 0 || skin >= static_cast<int>(m.skins.size())) continue;  // add_mesh names a bad skin
          for (int j : m.skins[skin].joints)
            if (j >= 0 && j < static_cast<int>(m.nodes.size()) && !seen[j])
              return c.err(idx("nodes", gn), "its skin " + std::to_string(skin) + " has joint node " + std::to_string(j) +
                                                 ", which is not in scene " + std::to_string(scene));
        }
    std::size_t levels = 1;
    for (const auto& b : bases) levels = std::max(levels, b.lod_nodes.size() + 1);
    out.lods.resize(levels);
    for (std::size_t l = 0; l < levels; ++l) {
      for (const auto& b : bases) {
        int gn = b.node;
        if (l > 0 && !b.lod_nodes.empty()) gn = b.lod_nodes[std::min(l, b.lod_nodes.size()) - 1];
        const tg::Node& n = m.nodes[gn];
        // A lower level without its own skin uses the base node's skin.
        int skin = n.skin >= 0 ? n.skin : (n.mesh >= 0 && gn != b.node ? m.nodes[b.node].skin : n.skin);
        if (auto s = add_mesh(out.lods[l], gn, n.mesh, skin); !s) return s;
      }
      float cov = 0.0f;
      for (const auto& b : bases)
        if (l < b.coverage.size() && std::isfinite(b.coverage[l])) cov = std::max(cov, static_cast<float>(b.coverage[l]));
      if (l + 1 == levels && levels > 1 && cov == 0.0f) cov = 0.0f;
      if (cov == 0.0f && l + 1 < levels) cov = std::pow(0.5f, static_cast<float>(l + 1));  // no coverage given
      out.lods[l].screen_coverage = l + 1 == levels ? 0.0f : cov;
      if (out.lods[l].indices.empty())
        return c.err(idx("nodes", bases.front().node), "LOD level " + std::to_string(l) + " has no triangles");
    }
    if (out.materials.empty()) out.materials.push_back(Material{glm::vec4(0.8f, 0.8f, 0.8f, 1.0f)});
    return Ok{};
  }

  Status animations() {
    const auto& m = c.m;
    for (std::size_t ai = 0; ai < m.animations.size(); ++ai) {
      const tg::Animation& a = m.animations[ai];
      std::string aw = idx("animations", static_cast<int>(ai));
      Clip clip;
      clip.name = a.name.empty() ? "clip" + std::to_string(ai) : a.name;
      for (std::size_t ci = 0; ci < a.channels.size(); ++ci) {
        const tg::AnimationChannel& ch = a.channels[ci];
        std::string cw = aw + ".channels[" + std::to_string(ci) + "]";
        Channel out_ch;
        if (ch.target_path == "weights") {  // morph weights: not played (the defaults are baked in)
          ++out.morph_report.weight_channels;
          continue;
        }
        if (ch.target_path == "translation") out_ch.path = ChannelPath::kTranslation;
        else if (ch.target_path == "rotation") out_ch.path = ChannelPath::kRotation;
        else if (ch.target_path == "scale") out_ch.path = ChannelPath::kScale;
        else return c.err(cw + ".target.path", "unknown path \"" + ch.target_path + "\"");
        if (ch.target_node < 0 || ch.target_node >= static_cast<int>(m.nodes.size()))
          return c.err(cw + ".target.node", "node " + std::to_string(ch.target_node) + " does not exist");
        out_ch.node = remap[ch.target_node];
        if (ch.sampler < 0 || ch.sampler >= static_cast<int>(a.samplers.size()))
          return c.err(cw + ".sampler", "sampler " + std::to_string(ch.sampler) + " does not exist");
        const tg::AnimationSampler& s = a.samplers[ch.sampler];
        std::string sw = aw + ".samplers[" + std::to_string(ch.sampler) + "]";
        if (s.interpolation == "STEP") out_ch.interpolation = Interpolation::kStep;
        else if (s.interpolation == "CUBICSPLINE") out_ch.interpolation = Interpolation::kCubicSpline;
        else if (s.interpolation.empty() || s.interpolation == "LINEAR") out_ch.interpolation = Interpolation::kLinear;
        else return c.err(sw + ".interpolation", "unknown interpolation \"" + s.interpolation + "\"");
        auto in = read_accessor(c, s.input, TINYGLTF_TYPE_SCALAR, {kF}, false, sw + ".input");
        if (!in) return in.error();
        for (std::size_t k = 0; k < in->size(); ++k) {
          if ((*in)[k] < 0.0) return c.err(idx("accessors", s.input), "key time " + std::to_string(k) + " is negative");
          if (k > 0 && !((*in)[k] > (*in)[k - 1]))
            return c.err(idx("accessors", s.input), "key times are not strictly increasing at element " + std::to_string(k));
          out_ch.times.push_back(static_cast<float>((*in)[k]));
        }
        bool rot = out_ch.path == ChannelPath::kRotation;
        auto outv = rot ? read_accessor(c, s.output, TINYGLTF_TYPE_VEC4, {kF, kB, kUB, kS, kUS}, true, sw + ".output")
                        : read_accessor(c, s.output, TINYGLTF_TYPE_VEC3, {kF}, false, sw + ".output");
        if (!outv) return outv.error();
        const int comps = rot ? 4 : 3;
        const std::size_t per_key = out_ch.interpolation == Interpolation::kCubicSpline ? 3 : 1;
        if (outv->size() / comps != out_ch.times.size() * per_key)
          return c.err(idx("accessors", s.output), "has " + std::to_string(outv->size() / comps) + " values for " +
                                                       std::to_string(out_ch.times.size()) + " key times");
        for (std::size_t k = 0; k < outv->size() / comps; ++k) {
          glm::vec4 v(outv->at(k * comps), outv->at(k * comps + 1), outv->at(k * comps + 2), rot ? outv->at(k * comps + 3) : 0.0);
          if (rot && (out_ch.interpolation != Interpolation::kCubicSpline || k % 3 == 1)) {
            float l = glm::length(v);
            if (!(l > 1e-6f)) return c.err(idx("accessors", s.output), "rotation " + std::to_string(k) + " is a zero quaternion");
            v /= l;
          }
          out_ch.values.push_back(v);
        }
        clip.duration = std::max(clip.duration, out_ch.times.back());
        clip.channels.push_back(std::move(out_ch));
      }
      out.clips.push_back(std::move(clip));
    }
    return Ok{};
  }
};

// EXT_meshopt_compression's fallback buffer has no data in a .glb (gltfpack -c), but tinygltf 2.7 gives every
// buffer without a uri the BIN chunk and refuses the file when the fallback is the longer one. Returns the
// file with each such fallback's byteLength set to 1 (tinygltf cannot hold an empty buffer; its views are
// decoded from the compressed buffer instead), or nothing when no buffer is a fallback.
std::optional<std::vector<unsigned char>> glb_without_fallback_lengths(const std::vector<unsigned char>& glb) {
  auto u32 = [&](std::size_t at) {
    std::uint32_t v;
    std::memcpy(&v, glb.data() + at, 4);
    return v;
  };
  if (glb.size() < 20 || std::memcmp(glb.data(), "glTF", 4) != 0 || u32(12) > glb.size() - 20 ||
      std::memcmp(glb.data() + 16, "JSON", 4) != 0)
    return std::nullopt;  // not for us to judge: tinygltf reports it
  const std::size_t json_len = u32(12);
  const std::string text(reinterpret_cast<const char*>(glb.data()) + 20, json_len);
  if (text.find("EXT_meshopt_compression") == std::string::npos) return std::nullopt;
  nlohmann::json j = nlohmann::json::parse(text, nullptr, false);
  if (j.is_discarded() || !j.is_object() || !j.contains("buffers") || !j["buffers"].is_array()) return std::nullopt;
  bool changed = false;
  for (std::size_t b = 1; b < j["buffers"].size(); ++b) {
    nlohmann::json& buf = j["buffers"][b];
    if (!buf.is_object() || buf.contains("uri")) continue;
    const auto ext = buf.find("extensions");
    if (ext == buf.end() || !ext->is_object() || !ext->contains("EXT_meshopt_compression")) continue;
    const nlohmann::json& e = (*ext)["EXT_meshopt_compression"];
    if (e.is_object() && e.value("fallback", false)) buf["byteLength"] = 1, changed = true;
  }
  if (!changed) return std::nullopt;
  std::string out_json = j.dump();
  while (out_json.size() % 4) out_json.push_back(' ');
  std::vector<unsigned char> out(glb.begin(), glb.begin() + 12);
  auto put = [&](std::uint32_t v) {
    unsigned char b[4];
    std::memcpy(b, &v, 4);
    out.insert(out.end(), b, b + 4);
  };
  put(static_cast<std::uint32_t>(out_json.size()));
  out.insert(out.end(), glb.begin() + 16, glb.begin() + 20);
  out.insert(out.end(), out_json.begin(), out_json.end());
  out.insert(out.end(), glb.begin() + 20 + json_len, glb.end());  // the BIN chunk, as it was
  const std::uint32_t total = static_cast<std::uint32_t>(out.size());
  std::memcpy(out.data() + 8, &total, 4);
  return out;
}

// The extensions this loader reads; a file that requires any other is refused by name.
// (KHR_meshopt_compression is not: its vertex data is in meshopt's version 1 format, which meshoptimizer
// 0.18, Debian 12's, cannot decode.)
constexpr const char* kReadExtensions[] = {"KHR_mesh_quantization", "KHR_texture_transform", "KHR_materials_unlit",
                                           "EXT_meshopt_compression", "EXT_texture_webp", "MSFT_lod"};

Status check_required_extensions(const Ctx& c) {
  for (std::size_t i = 0; i < c.m.extensionsRequired.size(); ++i) {
    const std::string& e = c.m.extensionsRequired[i];
    if (std::find_if(std::begin(kReadExtensions), std::end(kReadExtensions), [&](const char* k) { return e == k; }) !=
        std::end(kReadExtensions))
      continue;
    std::string known;
    for (const char* k : kReadExtensions) known += std::string(known.empty() ? "" : ", ") + k;
    return c.err("$.extensionsRequired[" + std::to_string(i) + "]",
                 "requires " + e + ", which this loader does not read (it reads " + known + ")");
  }
  return Ok{};
}

// EXT_meshopt_compression: every compressed buffer view is decoded into a buffer of its own and pointed at
// it, so accessors read plain bytes; the fallback buffer the views named is never read.
Status decode_meshopt(tg::Model& m, const Ctx& c) {
  for (std::size_t vi = 0; vi < m.bufferViews.size(); ++vi) {
    auto& exts = m.bufferViews[vi].extensions;
    auto it = exts.find("EXT_meshopt_compression");
    if (it == exts.end()) continue;
    const tg::Value& x = it->second;
    const std::string w = idx("bufferViews", static_cast<int>(vi)) + ".extensions." + it->first;
    auto whole = [&](const char* key, bool required, std::size_t fallback, std::size_t& v) -> Status {
      const tg::Value& n = x.Get(key);
      if (!n.IsNumber()) {
        if (required) return c.err(w + "." + key, "is missing or not a number");
        v = fallback;
        return Ok{};
      }
      const double d = n.GetNumberAsDouble();
      if (!(d >= 0.0 && d <= 4294967295.0) || d != std::floor(d))
        return c.err(w + "." + key, "must be a whole number from 0 (got " + std::to_string(d) + ")");
      v = static_cast<std::size_t>(d);
      return Ok{};
    };
    std::size_t buffer = 0, offset = 0, length = 0, stride = 0, count = 0;
    if (auto s = whole("buffer", true, 0, buffer); !s) return s;
    if (auto s = whole("byteOffset", false, 0, offset); !s) return s;
    if (auto s = whole("byteLength", true, 0, length); !s) return s;
    if (auto s = whole("byteStride", true, 0, stride); !s) return s;
    if (auto s = whole("count", true, 0, count); !s) return s;
    const std::string mode = x.Get("mode").IsString() ? x.Get("mode").Get<std::string>() : "";
    const std::string filter = x.Get("filter").IsString() ? x.Get("filter").Get<std::string>() : "NONE";
    if (buffer >= m.buffers.size()) return c.err(w + ".buffer", "buffer " + std::to_string(buffer) + " does not exist");
    const auto& src = m.buffers[buffer].data;
    if (offset > src.size() || length > src.size() - offset)
      return c.err(w, "byte range [" + std::to_string(offset) + ", " + std::to_string(offset + length) +
                          ") lies outside its buffer of " + std::to_string(src.size()) + " bytes");
    if (count == 0 || count > (1u << 26)) return c.err(w + ".count", "must be from 1 to 2^26 (got " + std::to_string(count) + ")");
    if (count * stride > (std::size_t{1} << 30))
      return c.err(w, "decodes to " + std::to_string(count * stride) + " bytes, more than the 1 GiB this loader takes");
    std::vector<unsigned char> dst;
    int rc = -1;
    if (mode == "ATTRIBUTES") {
      if (stride == 0 || stride % 4 != 0 || stride > 256)
        return c.err(w + ".byteStride", "must be a multiple of 4 up to 256 for ATTRIBUTES (got " + std::to_string(stride) + ")");
      dst.resize(count * stride);
      rc = meshopt_decodeVertexBuffer(dst.data(), count, stride, src.data() + offset, length);
      if (rc == 0 && filter != "NONE") {
        if (filter == "OCTAHEDRAL" && (stride == 4 || stride == 8)) meshopt_decodeFilterOct(dst.data(), count, stride);
        else if (filter == "QUATERNION" && stride == 8) meshopt_decodeFilterQuat(dst.data(), count, stride);
        else if (filter == "EXPONENTIAL") meshopt_decodeFilterExp(dst.data(), count, stride);
        else return c.err(w + ".filter", "filter \"" + filter + "\" with a stride of " + std::to_string(stride) + " is not one EXT_meshopt_compression defines");
      }
    } else if (mode == "TRIANGLES" || mode == "INDICES") {
      if (stride != 2 && stride != 4)
        return c.err(w + ".byteStride", "must be 2 or 4 for " + mode + " (got " + std::to_string(stride) + ")");
      if (mode == "TRIANGLES" && count % 3 != 0) return c.err(w + ".count", "must be a multiple of 3 for TRIANGLES");
      if (filter != "NONE") return c.err(w + ".filter", "only ATTRIBUTES take a filter");
      dst.resize(count * stride);
      rc = mode == "TRIANGLES" ? meshopt_decodeIndexBuffer(dst.data(), count, stride, src.data() + offset, length)
                               : meshopt_decodeIndexSequence(dst.data(), count, stride, src.data() + offset, length);
    } else {
      return c.err(w + ".mode", "must be ATTRIBUTES, TRIANGLES or INDICES (got \"" + mode + "\")");
    }
    if (rc != 0)
      return c.err(w, "the compressed data does not decode (corrupt, or a newer meshopt format than meshoptimizer " +
                          std::to_string(MESHOPTIMIZER_VERSION / 1000) + "." + std::to_string(MESHOPTIMIZER_VERSION % 1000 / 10) +
                          " reads)");
    tg::Buffer decoded;
    decoded.data = std::move(dst);
    tg::BufferView& bv = m.bufferViews[vi];
    bv.buffer = static_cast<int>(m.buffers.size());
    bv.byteOffset = 0;
    bv.byteLength = decoded.data.size();
    m.buffers.push_back(std::move(decoded));
  }
  return Ok{};
}

// Model::bake keeps palette.size() * 3 vec4 per frame of every clip at the bake rate, and up to two more per
// key of a STEP channel (BakedClip's step edges). A damaged key time (1e30 s) would overflow its frame count,
// or ask for terabytes and minutes: at most 2^20 frames and 1 GiB in all.
Status check_bake_size(const Model& model, float bake_rate, const std::string& path) {
  const double rate = bake_rate > 0.0f ? bake_rate : 60.0;  // as bake() takes it
  double frames = 0.0, longest = -1.0;
  int longest_clip = 0;
  for (std::size_t i = 0; i < model.clips.size(); ++i) {
    const double d = model.clips[i].duration;
    frames += d > 0.0 ? std::ceil(d * rate) + 1.0 : 1.0;
    for (const Channel& c : model.clips[i].channels)
      if (c.interpolation == Interpolation::kStep) frames += 2.0 * static_cast<double>(c.times.size());
    if (d > longest) longest = d, longest_clip = static_cast<int>(i);
  }
  const double bytes = frames * static_cast<double>(model.palette.size()) * 3.0 * sizeof(glm::vec4);
  if (frames <= double(1 << 20) && bytes <= double(1 << 30)) return Ok{};
  char text[200];
  std::snprintf(text, sizeof text,
                "lasts %g s: baking the clips at %g frames per second takes %.0f frames of %zu matrices, more than "
                "the 2^20 frames or 1 GiB this loader takes",
                longest, rate, frames, model.palette.size());
  return Error{path, idx("animations", longest_clip), text};
}

}  // namespace

Result<Model> load_model(const std::string& path, const LoadOptions& options) {
  namespace fs = std::filesystem;
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) return Error{path, "", "no such file"};
  auto size = fs::file_size(path, ec);
  if (ec) return Error{path, "", "cannot read: " + ec.message()};
  tg::Model gm;
  tg::TinyGLTF loader;
  ImageContext images{&gm, path, std::nullopt};
  loader.SetImageLoader(load_image, &images);
  loader.SetFsCallbacks(tg::FsCallbacks{file_exists, tg::ExpandFilePath, read_whole_file, tg::WriteWholeFile, nullptr});
  std::string err, warn;
  bool ok = false;
  const bool binary = fs::path(path).extension() == ".glb" || fs::path(path).extension() == ".GLB";
  if (size > 0xffffffffu) return Error{path, "", "file is larger than 4 GiB, the most glTF can be"};
  try {
    std::vector<unsigned char> bytes(size);
    std::ifstream in(path, std::ios::binary);
    if (!in.read(reinterpret_cast<char*>(bytes.data()), static_cast<std::streamsize>(size)))
      return Error{path, "", "cannot read the file"};
    const std::string base = fs::path(path).parent_path().string();
    // The container and the document are checked here first: tinygltf's own messages name no place.
    if (binary) {
      if (auto patched = glb_without_fallback_lengths(bytes)) bytes = std::move(*patched);
      if (bytes.size() > 0xffffffffu) return Error{path, "", "file is larger than 4 GiB, the most a .glb can be"};
      auto glb = detail::check_glb_container(bytes.data(), bytes.size(), path);
      if (!glb) return glb.error();
      const std::string_view text(reinterpret_cast<const char*>(bytes.data()) + glb->json_at, glb->json_length);
      if (auto s = detail::check_gltf_json(text, path, &*glb); !s) return s.error();
    } else {
      const std::string_view text(reinterpret_cast<const char*>(bytes.data()), bytes.size());
      if (auto s = detail::check_gltf_json(text, path, nullptr); !s) return s.error();
    }
    const auto n = static_cast<unsigned int>(bytes.size());
    if (binary) ok = loader.LoadBinaryFromMemory(&gm, &err, &warn, bytes.data(), n, base);
    else ok = loader.LoadASCIIFromString(&gm, &err, &warn, reinterpret_cast<const char*>(bytes.data()), n, base);
  } catch (const std::exception& e) {
    return Error{path, "", std::string("parse error: ") + e.what()};
  } catch (...) {
    return Error{path, "", "parse error"};
  }
  if (!ok && images.error) return *images.error;
  if (!ok) {
    while (!err.empty() && (err.back() == '\n' || err.back() == ' ')) err.pop_back();
    return Error{path, "", err.empty() ? "not a valid glTF file" : err};
  }
  Model model;
  model.name = fs::path(path).stem().string();
  Ctx c{gm, path};
  try {
    if (auto s = check_required_extensions(c); !s) return s.error();
    if (auto s = decode_meshopt(gm, c); !s) return s.error();
    Builder b{c, model};
    b.quantized = std::find(gm.extensionsUsed.begin(), gm.extensionsUsed.end(), "KHR_mesh_quantization") != gm.extensionsUsed.end();
    if (auto s = b.hierarchy(); !s) return s.error();
    if (auto s = b.samplers(); !s) return s.error();
    if (auto s = b.meshes(); !s) return s.error();
    if (auto s = b.animations(); !s) return s.error();
    if (auto s = check_bake_size(model, options.bake_rate, path); !s) return s.error();
  } catch (const std::exception& e) {
    return Error{path, "", std::string("cannot build the model: ") + e.what()};
  }
  add_generated_lods(model, options);
  if (options.optimize_vertex_order) optimize_vertex_order(model);
  model.bake(options.bake_rate);
  return model;
}

}  // namespace bb::runtime
