#include "bb/modeler/body.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>

#include "bb/modeler/implicit_surface.h"
#include "json_util.h"

namespace bb::modeler {

using namespace detail;

int Body::count(PrimitiveType t) const {
  return static_cast<int>(std::count_if(primitives.begin(), primitives.end(),
                                        [t](const Primitive& p) { return p.type == t; }));
}

float Body::height() const {
  ImplicitSurface s(*this, skeleton->neutral());
  const Aabb& b = s.bounds();
  // The top is the last exit of upward rays through the highest primitives; the bottom the last
  // exit of downward rays through the lowest ones. A small fan of columns around each.
  std::vector<const PlacedPrimitive*> by_y;
  for (const auto& p : s.primitives()) by_y.push_back(&p);
  auto probe = [&](bool up) {
    std::sort(by_y.begin(), by_y.end(), [&](auto* a, auto* c) {
      return up ? a->support.max.y > c->support.max.y : a->support.min.y < c->support.min.y;
    });
    float best = up ? -1e30f : 1e30f;
    for (size_t i = 0; i < std::min<size_t>(4, by_y.size()); ++i) {
      for (int dx = -2; dx <= 2; ++dx)
        for (int dz = -2; dz <= 2; ++dz) {
          glm::vec3 c = by_y[i]->center + glm::vec3(dx, 0, dz) * 0.01f;
          glm::vec3 o(c.x, up ? b.min.y - 0.01f : b.max.y + 0.01f, c.z);
          glm::vec3 d(0, up ? 1.0f : -1.0f, 0);
          float len = b.size().y + 0.02f;
          if (auto t = s.outermost_intersection(o, d, len)) {
            float y = o.y + d.y * *t;
            best = up ? std::max(best, y) : std::min(best, y);
          }
        }
    }
    return best;
  };
  float top = probe(true), bottom = probe(false);
  return top > bottom ? top - bottom : 0.0f;
}

namespace {

// The name as an error message may show it: bytes that are not printable ASCII as \xNN.
std::string shown(std::string_view name) {
  std::string out;
  for (unsigned char c : name.substr(0, 60)) {
    if (c >= 0x20 && c < 0x7F && c != '\\' && c != '"') {
      out += static_cast<char>(c);
    } else {
      char b[8];
      std::snprintf(b, sizeof b, "\\x%02X", c);
      out += b;
    }
  }
  return name.size() > 60 ? out + "..." : out;
}

// Length in bytes of the valid UTF-8 sequence at s[i] (overlong forms, surrogates and code points past
// U+10FFFF are invalid), 0 when there is none; `cp` gets its code point.
size_t utf8_sequence(std::string_view s, size_t i, uint32_t& cp) {
  const auto byte = [&](size_t k) { return static_cast<unsigned char>(s[k]); };
  const unsigned char c = byte(i);
  size_t n;
  if (c < 0x80) { cp = c; return 1; }
  if (c >= 0xC2 && c <= 0xDF) { n = 2; cp = c & 0x1F; }
  else if (c >= 0xE0 && c <= 0xEF) { n = 3; cp = c & 0x0F; }
  else if (c >= 0xF0 && c <= 0xF4) { n = 4; cp = c & 0x07; }
  else return 0;
  if (i + n > s.size()) return 0;
  for (size_t k = 1; k < n; ++k) {
    if ((byte(i + k) & 0xC0) != 0x80) return 0;
    cp = (cp << 6) | (byte(i + k) & 0x3F);
  }
  if ((n == 3 && cp < 0x800) || (n == 4 && cp < 0x10000) || (cp >= 0xD800 && cp <= 0xDFFF) || cp > 0x10FFFF) return 0;
  return n;
}

}  // namespace

std::string body_name_problem(std::string_view name) {
  const std::string rule =
      "a body name becomes an output file's name, so it must be 1 to " + std::to_string(kMaxBodyNameBytes) +
      " bytes of UTF-8 without '/', '\\' or control characters, and not \".\" or \"..\"";
  if (name.empty()) return "body name is empty: " + rule;
  if (name.size() > kMaxBodyNameBytes)
    return "body name is " + std::to_string(name.size()) + " bytes long: " + rule;
  if (name == "." || name == "..") return "body name \"" + std::string(name) + "\" names a directory: " + rule;
  for (size_t i = 0; i < name.size();) {
    uint32_t cp = 0;
    const size_t n = utf8_sequence(name, i, cp);
    if (n == 0) return "body name \"" + shown(name) + "\" is not valid UTF-8 (at byte " + std::to_string(i) + "): " + rule;
    if (cp == '/' || cp == '\\')
      return "body name \"" + shown(name) + "\" holds a '" + static_cast<char>(cp) + "': " + rule;
    if (cp < 0x20 || (cp >= 0x7F && cp <= 0x9F))
      return "body name \"" + shown(name) + "\" holds a control character (at byte " + std::to_string(i) + "): " + rule;
    i += n;
  }
  return {};
}

Result<Body> parse_body(std::string_view text, std::string_view file, const std::string& base_dir) {
  Body body;
  try {
    json doc = parse_text(text);
    const std::string root = "$";
    if (!doc.is_object()) fail(root, "expected an object at the top level");
    body.name = string(member(doc, root, "name"), at(root, "name"));
    if (std::string problem = body_name_problem(body.name); !problem.empty()) fail(at(root, "name"), problem);
    if (auto it = doc.find("skeleton"); it != doc.end()) {
      std::string rel = string(*it, at(root, "skeleton"));
      std::filesystem::path p = std::filesystem::path(base_dir) / rel;
      auto sk = load_skeleton(p.lexically_normal().string());
      if (!sk) {
        Error e = sk.error();
        if (e.where.empty()) e.where = "(referenced from " + std::string(file) + " $.skeleton)";
        throw e;
      }
      body.skeleton = std::make_shared<Skeleton>(std::move(*sk));
    } else {
      body.skeleton = std::shared_ptr<const Skeleton>(&default_skeleton(), [](const Skeleton*) {});
    }
    if (auto it = doc.find("sample_posture"); it != doc.end()) {
      body.sample_posture = string(*it, at(root, "sample_posture"));
      const auto& names = body.skeleton->posture_names();
      if (body.sample_posture != "neutral" &&
          std::find(names.begin(), names.end(), body.sample_posture) == names.end())
        fail(at(root, "sample_posture"), "unknown posture \"" + body.sample_posture + "\"");
    }
    std::string pp = at(root, "primitives");
    const json& arr = array(member(doc, root, "primitives"), pp);
    if (arr.empty()) fail(pp, "a body needs at least one primitive");
    for (size_t i = 0; i < arr.size(); ++i) {
      std::string p = at(pp, i);
      const json& o = arr[i];
      Primitive pr;
      if (!o.is_object()) fail(p, std::string("expected an object, got ") + type_name(o));
      if (auto it = o.find("name"); it != o.end()) pr.name = string(*it, at(p, "name"));
      std::string type = string(member(o, p, "type"), at(p, "type"));
      if (type == "ellipsoid") pr.type = PrimitiveType::kEllipsoid;
      else if (type == "metaball") pr.type = PrimitiveType::kMetaball;
      else fail(at(p, "type"), "unknown primitive type \"" + type + "\" (expected ellipsoid or metaball)");
      std::string joint = string(member(o, p, "joint"), at(p, "joint"));
      pr.joint = body.skeleton->find_joint(joint);
      if (pr.joint < 0) fail(at(p, "joint"), "unknown joint \"" + joint + "\"");
      pr.center = vec3(member(o, p, "center"), at(p, "center"));
      pr.radii = vec3(member(o, p, "radii"), at(p, "radii"));
      for (int k = 0; k < 3; ++k) {
        if (!(pr.radii[k] > 0.0f))
          fail(at(at(p, "radii"), k), "radius must be positive (got " + number_text(pr.radii[k]) + ")");
        if (!(pr.radii[k] <= kMaxPrimitiveExtent))
          fail(at(at(p, "radii"), k), "radius must be at most " + number_text(kMaxPrimitiveExtent) + " m (got " + number_text(pr.radii[k]) + ")");
        if (!(std::abs(pr.center[k]) <= kMaxPrimitiveExtent))
          fail(at(at(p, "center"), k),
               "the centre must lie within " + number_text(kMaxPrimitiveExtent) + " m of its joint (got " + number_text(pr.center[k]) + ")");
      }
      if (auto it = o.find("rotation_deg"); it != o.end()) {
        const glm::vec3 deg = vec3(*it, at(p, "rotation_deg"));
        for (int k = 0; k < 3; ++k)
          if (!(std::abs(deg[k]) <= 360.0f))
            fail(at(at(p, "rotation_deg"), k), "an angle must lie in [-360, 360] degrees (got " + number_text(deg[k]) + ")");
        pr.orientation = glm::quat(glm::radians(deg));
      }
      if (auto it = o.find("strength"); it != o.end()) {
        pr.strength = static_cast<float>(number(*it, at(p, "strength")));
        if (!(pr.strength > 0.0f) || !std::isfinite(pr.strength)) fail(at(p, "strength"), "strength must be positive and finite");
      }
      body.primitives.push_back(std::move(pr));
    }
  } catch (const JsonError& e) {
    return Error{std::string(file), e.where, e.reason};
  } catch (const Error& e) {
    return e;
  }
  return body;
}

Result<Body> load_body(const std::string& path) {
  auto text = read_file(path);
  if (!text) return text.error();
  std::filesystem::path base = std::filesystem::path(path).parent_path();
  return parse_body(*text, path, base.empty() ? "." : base.string());
}

namespace {

// SplitMix64: a small deterministic generator, the same on every platform.
struct Rng {
  uint64_t s;
  uint64_t next() {
    uint64_t z = (s += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
  }
  float uniform(float lo, float hi) { return lo + (hi - lo) * static_cast<float>((next() >> 40) * 0x1.0p-24); }
};

// Body regions that vary together in a random variant.
int region_of(const std::string& joint) {
  auto has = [&](const char* s) { return joint.find(s) != std::string::npos; };
  if (has("hip") || has("knee") || has("sacroiliac")) return 0;           // legs and hips
  if (has("vl5")) return 1;                                               // belly
  if (has("vt10") || has("sternoclavicular")) return 2;                   // chest and shoulders
  if (has("shoulder") || has("elbow")) return 3;                          // arms
  return 4;                                                               // head, neck, hands, feet
}

}  // namespace

Body make_variant(const Body& body, const BodyShape& shape, std::string_view suffix) {
  Body out = body;
  if (!suffix.empty()) out.name += suffix;
  float height_scale = 1.0f;
  if (shape.height_m > 0) {
    float h = body.height();
    if (h > 0) height_scale = shape.height_m / h;
  }
  float girth[5] = {1, 1, 1, 1, 1};
  float limb_length = 1.0f, build = shape.build;
  if (shape.seed != 0) {
    Rng rng{shape.seed};
    if (shape.height_m <= 0) height_scale *= rng.uniform(0.92f, 1.08f);
    build *= rng.uniform(0.88f, 1.18f);
    limb_length = rng.uniform(0.96f, 1.04f);
    for (float& g : girth) g = rng.uniform(0.9f, 1.12f);
    girth[4] = rng.uniform(0.97f, 1.03f);
  }
  // Skeleton: scale all offsets, legs and arms a little more or less (proportions).
  Skeleton sk = *body.skeleton;
  for (size_t ji = 0; ji < sk.joints().size(); ++ji) {
    const Joint& j = sk.joints()[ji];
    float s = height_scale;
    bool limb = j.name.find("knee") != std::string::npos || j.name.find("ankle") != std::string::npos ||
                j.name.find("elbow") != std::string::npos || j.name.find("wrist") != std::string::npos;
    if (limb) s *= limb_length;
    // The root's height follows the legs.
    if (ji == 0) s *= limb_length;
    sk.set_offset(static_cast<int>(ji), j.offset * s);
  }
  out.skeleton = std::make_shared<Skeleton>(std::move(sk));
  for (Primitive& p : out.primitives) {
    p.center *= height_scale;
    p.radii *= height_scale;
    if (p.type == PrimitiveType::kMetaball) {
      float g = build * girth[region_of(body.skeleton->joints()[p.joint].name)];
      if (region_of(body.skeleton->joints()[p.joint].name) == 4) g = std::sqrt(g) * girth[4];
      // Girth grows across the link; along the link (local Y for limbs) less so.
      p.radii.x *= g;
      p.radii.z *= g;
      p.radii.y *= 0.5f * (1.0f + g);
    }
  }
  return out;
}

}  // namespace bb::modeler
