// Deterministic mutation fuzzing of the body reader (load_body): the repository's default body
// (data/bodies/default.json, the built-in one) and a small hand-written body that names its skeleton
// file are mutated a few hundred times each (JSON edits that know the body's structure, troublesome
// numbers, swapped tokens, deep nesting, bytes damaged, the file cut short), every mutant is written to a
// file and loaded. Each load must return: a body that keeps the documented limits, or an error that names
// the file. BB_FUZZ_ITERATIONS=N sets the mutants per seed file (to look harder).
#include <cctype>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <limits>
#include <random>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "bb/modeler/body.h"

namespace bb::modeler {
namespace {

namespace fs = std::filesystem;
using json = nlohmann::json;

int iterations(int fallback) {
  if (const char* s = std::getenv("BB_FUZZ_ITERATIONS"); s && std::atoi(s) > 0) return std::atoi(s);
  return fallback;
}

std::string read_text(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

const char* const kNumberTexts[] = {"0",     "-1",    "1",     "2",          "2.0000001",  "1e30",  "-1e30",
                                    "nan",   "NaN",   "inf",   "4294967295", "2147483648", "1e-45", "1e308",
                                    "1e400", "-1e400", "-0",   "360",        "360.0001",   "-361",  "0.05",
                                    "18446744073709551615", "99999999999999999999999"};
const json kValues[] = {0, -1, 1, 2, 2.0000001, 1e30, -1e30, 4294967295.0, 2147483648.0, 1e-45, 1.7e308, -0.0,
                        360, 360.0001, -361, 0.05, nullptr, "x", "", true, json::array(), json::object(),
                        json::array({1, 2, 3}), json::array({0.1, 0.1}), json::array({0.1, 0.1, 0.1, 0.1}),
                        "ellipsoid", "metaball", "l_elbow", "sacroiliac", "bind", "neutral", "max_extent",
                        "skeleton.json", "", ".", "..", "/", "nope.json", "./skeleton.json", "small.json"};
const std::set<std::string> kHotKeys = {"name",   "type",         "joint",    "center",         "radii",
                                        "strength", "rotation_deg", "skeleton", "sample_posture", "primitives"};

class Mutator {
  struct Site {
    json::json_pointer ptr;
    std::string key;
  };

 public:
  explicit Mutator(std::uint32_t seed) : rng_(seed) {}
  std::size_t below(std::size_t n) { return n == 0 ? 0 : std::uniform_int_distribution<std::size_t>(0, n - 1)(rng_); }
  bool chance(int percent) { return static_cast<int>(below(100)) < percent; }
  template <class T, std::size_t N>
  const T& pick(const T (&a)[N]) { return a[below(N)]; }

  // A mutant of the JSON document `doc` (as text).
  std::string mutant(const json& doc) {
    const std::size_t kind = below(20);
    if (kind < 10) {  // structure-aware edits
      json j = doc;
      for (int e = 1 + static_cast<int>(below(3)); e > 0; --e) edit(j);
      return j.dump(1);
    }
    std::string t = doc.dump(1);
    if (kind < 15) {
      tokens(t);
      if (chance(30)) tokens(t);
    } else if (kind < 19) {
      bytes(t);
    } else {  // a value buried deep in arrays or objects: an unknown key's, or one that breaks the document
      const std::size_t depth = chance(50) ? 1000 : 100000;
      const bool arrays = chance(50);
      std::string deep;
      for (std::size_t d = 0; d < depth; ++d) deep += arrays ? "[" : "{\"a\":";
      deep += "0";
      for (std::size_t d = 0; d < depth; ++d) deep += arrays ? "]" : "}";
      if (chance(50)) t.insert(1, "\"deep\": " + deep + ",");
      else if (const std::size_t at = t.find("\"radii\":"); at != std::string::npos) t.insert(at + 8, deep + ",");
    }
    return t;
  }

 private:
  std::mt19937 rng_;

  void edit(json& doc) {
    std::vector<Site> all, hot;
    collect(doc, json::json_pointer(), "", all, hot);
    if (all.empty()) return;
    const Site& s = !hot.empty() && chance(70) ? hot[below(hot.size())] : all[below(all.size())];
    json& v = doc[s.ptr];
    switch (below(6)) {
      case 0:
      case 1:
        v = pick(kValues);
        break;
      case 2: {  // removed
        json& parent = doc[s.ptr.parent_pointer()];
        if (parent.is_object()) parent.erase(s.ptr.back());
        else if (parent.is_array() && !parent.empty()) parent.erase(parent.begin() + std::stoi(s.ptr.back()));
        break;
      }
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
      case 4: {  // swapped with another place's value
        json& w = doc[all[below(all.size())].ptr];
        if (&w != &v && !contains(v, w) && !contains(w, v)) std::swap(v, w);
        break;
      }
      default:  // a key added to an object (unknown keys, a second skeleton, a posture)
        if (v.is_object()) v[pick({"skeleton", "sample_posture", "strength", "rotation_deg", "zzz"})] = pick(kValues);
        else if (v.is_number()) v = v.get<double>() * (chance(50) ? -1.0 : 1e10);
        else v = pick(kValues);
    }
  }

  static bool contains(const json& outer, const json& inner) {
    if (&outer == &inner) return true;
    if (outer.is_structured())
      for (const json& e : outer)
        if (contains(e, inner)) return true;
    return false;
  }

  static void collect(const json& j, const json::json_pointer& p, const std::string& key, std::vector<Site>& all,
                      std::vector<Site>& hot) {
    if (!p.empty()) {
      all.push_back({p, key});
      if (kHotKeys.count(key)) hot.push_back({p, key});
    }
    if (j.is_object()) {
      for (auto it = j.begin(); it != j.end(); ++it) collect(it.value(), p / it.key(), it.key(), all, hot);
    } else if (j.is_array()) {
      for (std::size_t i = 0; i < j.size(); ++i) collect(j[i], p / i, key, all, hot);
    }
  }

  // A number replaced by a troublesome one, or two tokens swapped.
  void tokens(std::string& t) {
    struct Tok { std::size_t at, n; bool number; };
    std::vector<Tok> toks;
    for (std::size_t i = 0; i < t.size();) {
      const char ch = t[i];
      if (ch == '"') {
        std::size_t e = i + 1;
        while (e < t.size() && t[e] != '"') e += t[e] == '\\' ? 2 : 1;
        e = std::min(e + 1, t.size());
        toks.push_back({i, e - i, false});
        i = e;
      } else if (ch == '-' || (ch >= '0' && ch <= '9')) {
        std::size_t e = i + 1;
        while (e < t.size() && t[e] && std::strchr("0123456789.eE+-", t[e])) ++e;
        toks.push_back({i, e - i, true});
        i = e;
      } else if (ch && std::strchr("{}[],:", ch)) {
        toks.push_back({i, 1, false});
        ++i;
      } else if (std::isalpha(static_cast<unsigned char>(ch))) {
        std::size_t e = i;
        while (e < t.size() && std::isalpha(static_cast<unsigned char>(t[e]))) ++e;
        toks.push_back({i, e - i, false});
        i = e;
      } else {
        ++i;
      }
    }
    if (toks.size() < 2) return bytes(t);
    if (chance(60)) {
      std::vector<Tok> nums;
      for (const Tok& k : toks)
        if (k.number) nums.push_back(k);
      if (!nums.empty()) {
        const Tok& k = nums[below(nums.size())];
        t.replace(k.at, k.n, pick(kNumberTexts));
        return;
      }
    }
    Tok a = toks[below(toks.size())], b = toks[below(toks.size())];
    if (a.at > b.at) std::swap(a, b);
    if (a.at == b.at) return;
    const std::string ta = t.substr(a.at, a.n), tb = t.substr(b.at, b.n);
    t.replace(b.at, b.n, ta);
    t.replace(a.at, a.n, tb);
  }

  void bytes(std::string& b) {
    if (b.empty()) return b.push_back('{');
    switch (below(5)) {
      case 0: b[below(b.size())] ^= static_cast<char>(1u << below(8)); break;
      case 1: b[below(b.size())] = static_cast<char>(below(256)); break;
      case 2: b.resize(below(b.size())); break;
      case 3: {
        const std::size_t at = below(b.size()), n = 1 + below(std::min<std::size_t>(64, b.size() - at));
        b.erase(at, n);
        break;
      }
      default: {
        const std::size_t at = below(b.size()), n = 1 + below(std::min<std::size_t>(64, b.size() - at));
        b.insert(below(b.size() + 1), b.substr(at, n));
      }
    }
  }
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

void fuzz(const std::string& name, const std::string& seed_text, std::uint32_t rng_seed, int count) {
  const fs::path dir = fs::temp_directory_path() / ("bb_body_fuzz_" + name);  // one per test: ctest runs them at once
  fs::create_directories(dir);
  // Beside the mutants: a skeleton for the bodies that name one (a copy of the repository's).
  std::ofstream(dir / "skeleton.json", std::ios::binary) << read_text(fs::path(BB_DATA_DIR) / "skeleton.json");
  const fs::path path = dir / (name + ".json");
  auto write = [&](const std::string& text) { std::ofstream(path, std::ios::binary | std::ios::trunc) << text; };
  write(seed_text);
  {
    auto b = load_body(path.string());
    ASSERT_TRUE(b.ok()) << "the seed " << name << " does not load: " << b.error().message();
  }
  const json doc = json::parse(seed_text);
  Mutator m(rng_seed);
  int accepted = 0, rejected = 0;
  bool failed = false;
  std::vector<std::string> samples;
  std::set<std::string> seen;
  for (int i = 0; i < count; ++i) {
    const std::string text = m.mutant(doc);
    write(text);
    auto b = load_body(path.string());
    std::string problem;
    if (b.ok()) {
      ++accepted;
      problem = check_body(*b);
    } else {
      ++rejected;
      const std::string msg = b.error().message();
      if (msg.find(path.string()) == std::string::npos || b.error().reason.empty())
        problem = "the error does not name the file and a reason: " + msg;
      else if (samples.size() < 4 && seen.insert(b.error().reason.substr(0, 20)).second)
        samples.push_back(msg.substr(0, 200));
    }
    if (!problem.empty()) {
      const fs::path keep = dir / ("failing_" + name + "_" + std::to_string(i) + ".json");
      std::ofstream(keep, std::ios::binary) << text;
      ADD_FAILURE() << name << " mutant " << i << " (kept as " << keep.string() << "): " << problem;
      failed = true;
      break;  // the first failing mutant of a seed is enough to look at
    }
  }
  std::cout << "[fuzz] " << name << ".json: " << count << " mutants, " << accepted << " accepted, " << rejected
            << " rejected\n";
  for (const std::string& s : samples) std::cout << "[fuzz]   e.g. " << s << "\n";
  if (!failed) fs::remove_all(dir);
}

TEST(BodyFuzz, DefaultBody) {
  // The built-in body's text: the modeler embeds data/bodies/default.json at build time.
  fuzz("default", read_text(fs::path(BB_DATA_DIR) / "bodies" / "default.json"), 4101u, iterations(1000));
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
  fuzz("small", small, 4102u, iterations(1500));
}

}  // namespace
}  // namespace bb::modeler
