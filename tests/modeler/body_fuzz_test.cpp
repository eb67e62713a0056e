// Deterministic mutation fuzzing of the body reader (load_body): the repository's default body
// (data/bodies/default.json, the built-in one) and a small hand-written body that names its skeleton
// file are mutated a few hundred times each (JSON edits that know the body's structure, troublesome
// numbers, swapped tokens, deep nesting, bytes damaged, the file cut short), every mutant is written to a
// file and loaded. Each load must return: a body that keeps the documented limits, or an error that names
// the file, a place in it (a JSON path, a line and column) and a reason. BB_FUZZ_ITERATIONS=N sets
// the mutants per seed file (to look harder).
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <set>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "bb/modeler/body.h"
#include "fuzz.h"

namespace bb::modeler {
namespace {

namespace fs = std::filesystem;
namespace fuzz = bb::test::fuzz;
using json = nlohmann::json;

// Numbers that trouble a body reader besides the common ones: just past the 2 m limit of radii and centres,
// angles around a full turn, the default radius, a negative overflow.
const std::vector<const char*> kNumberTexts =
    fuzz::number_texts({"2.0000001", "-1e400", "360", "360.0001", "-361", "0.05"});
const json kValues[] = {0, -1, 1, 2, 2.0000001, 1e30, -1e30, 4294967295.0, 2147483648.0, 1e-45, 1.7e308, -0.0,
                        360, 360.0001, -361, 0.05, nullptr, "x", "", true, json::array(), json::object(),
                        json::array({1, 2, 3}), json::array({0.1, 0.1}), json::array({0.1, 0.1, 0.1, 0.1}),
                        "ellipsoid", "metaball", "l_elbow", "sacroiliac", "bind", "neutral", "max_extent",
                        "skeleton.json", "", ".", "..", "/", "nope.json", "./skeleton.json", "small.json"};
const std::set<std::string> kHotKeys = {"name",   "type",         "joint",    "center",         "radii",
                                        "strength", "rotation_deg", "skeleton", "sample_posture", "primitives"};

class Mutator : public fuzz::Random {
 public:
  using Random::Random;

  // A mutant of the JSON document `doc` (as text).
  std::string mutant(const json& doc) {
    const std::size_t kind = below(20);
    if (kind < 10) {  // structure-aware edits
      json j = doc;
      for (int e = 1 + static_cast<int>(below(3)); e > 0; --e) edit(j);
      return j.dump(1);
    }
    std::string t = doc.dump(1);
    if (kind < 15) {  // a number replaced by a troublesome one, or two tokens swapped
      tokens(t);
      if (chance(30)) tokens(t);
    } else if (kind < 19) {
      bytes(t);
    } else {  // a value buried deep in arrays or objects: an unknown key's, or one that breaks the document
      const std::string deep = fuzz::deep_value(*this);
      if (chance(50)) t.insert(1, "\"deep\": " + deep + ",");
      else if (const std::size_t at = t.find("\"radii\":"); at != std::string::npos) t.insert(at + 8, deep + ",");
    }
    return t;
  }

 private:
  void edit(json& doc) {
    const fuzz::Sites sites(doc, kHotKeys);
    if (sites.all.empty()) return;
    const json::json_pointer& ptr = sites.pick(*this);
    json& v = doc[ptr];
    switch (below(6)) {
      case 0:
      case 1:
        v = pick(kValues);
        break;
      case 2:  // removed
        fuzz::erase_at(doc, ptr);
        break;
      case 3:  // an array grows or shrinks
        if (v.is_array() && !v.empty() && chance(50)) {
          v.erase(v.begin() + below(v.size()));
        } else if (v.is_array()) {
          const json copy = v.empty() ? json(0.1) : v[below(v.size())];
          v.insert(v.begin() + below(v.size() + 1), copy);
        } else {
          v = json::array({v});
        }
        break;
      case 4:  // swapped with another place's value
        fuzz::swap_with_another(*this, doc, v, sites);
        break;
      default:  // a key added to an object (unknown keys, a second skeleton, a posture)
        if (v.is_object()) v[pick({"skeleton", "sample_posture", "strength", "rotation_deg", "zzz"})] = pick(kValues);
        else if (v.is_number()) v = v.get<double>() * (chance(50) ? -1.0 : 1e10);
        else v = pick(kValues);
    }
  }

  void tokens(std::string& t) {
    if (!fuzz::damage_json_tokens(*this, t, kNumberTexts)) bytes(t);
  }
  void bytes(std::string& t) { fuzz::damage_bytes(*this, t, '{'); }
};

// What a loaded body promises (body.h): primitives on real joints, radii in (0, 2] m, centres within 2 m,
// a positive finite strength, a unit orientation. Returns what is wrong, or nothing.
std::string check_body(const Body& b) {
  if (!b.skeleton || b.primitives.empty() || b.name.empty()) return "no skeleton, primitives or name";
  for (std::size_t i = 0; i < b.primitives.size(); ++i) {
    const Primitive& p = b.primitives[i];
    const std::string at = "primitive " + std::to_string(i) + ": ";
    if (!(p.joint >= 0 && p.joint < static_cast<int>(b.skeleton->joints().size()))) return at + "joint out of range";
    for (int k = 0; k < 3; ++k) {
      if (!(p.radii[k] > 0.0f && p.radii[k] <= kMaxPrimitiveExtent)) return at + "radius out of range";
      if (!(std::abs(p.center[k]) <= kMaxPrimitiveExtent)) return at + "centre out of range";
    }
    if (!(std::isfinite(p.strength) && p.strength > 0.0f)) return at + "strength not positive and finite";
    if (!(std::abs(glm::length(p.orientation) - 1.0f) < 1e-4f)) return at + "orientation not a unit quaternion";
  }
  return {};
}

void fuzz_body(const std::string& name, const std::string& seed_text, std::uint32_t rng_seed, int count) {
  const fs::path dir = fuzz::fresh_dir("bb_body_fuzz_" + name);
  // Beside the mutants: a skeleton for the bodies that name one (a copy of the repository's).
  fuzz::write_file(dir / "skeleton.json", fuzz::read_file(fs::path(BB_DATA_DIR) / "skeleton.json"));
  const json doc = json::parse(seed_text);
  Mutator m(rng_seed);
  auto mutant = [&] { return m.mutant(doc); };
  auto load = [](const std::string& path) { return load_body(path); };
  if (fuzz::run(dir / (name + ".json"), seed_text, count, mutant, load, check_body)) fs::remove_all(dir);
}

TEST(BodyFuzz, DefaultBody) {
  // The built-in body's text: the modeler embeds data/bodies/default.json at build time.
  fuzz_body("default", fuzz::read_file(fs::path(BB_DATA_DIR) / "bodies" / "default.json"), 4101u,
            fuzz::iterations(1000));
}

TEST(BodyFuzz, SmallBodyWithItsOwnSkeletonFile) {
  const std::string small = R"({
  "name": "small",
  "skeleton": "skeleton.json",
  "sample_posture": "bind",
  "primitives": [
    {"name": "pelvis", "type": "ellipsoid", "joint": "sacroiliac", "center": [0, 0, -0.01], "radii": [0.12, 0.075, 0.075]},
    {"name": "l_thigh", "type": "metaball", "joint": "l_hip", "center": [0, -0.2, 0], "radii": [0.07, 0.2, 0.07],
     "rotation_deg": [5, 0, -3], "strength": 1.2},
    {"type": "metaball", "joint": "r_knee", "center": [0, -0.2, 0.01], "radii": [0.05, 0.2, 0.05], "strength": 0.9}
  ]
})";
  fuzz_body("small", small, 4102u, fuzz::iterations(1500));
}

}  // namespace
}  // namespace bb::modeler
