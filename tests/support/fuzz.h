// Tests: what the mutation fuzz tests (glTF, BVH, body) share: the mutant count (BB_FUZZ_ITERATIONS), a
// seeded random source, byte damage, troublesome number texts, token damage of JSON text, deep nesting,
// the places of a JSON document to edit, the shared data files, and the run that loads every mutant of a
// seed and checks the contract: a valid result, or an error that names the file, a place in it and a reason.
#pragma once

#include <algorithm>
#include <cctype>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <initializer_list>
#include <iostream>
#include <random>
#include <set>
#include <sstream>
#include <string>
#include <string_view>
#include <vector>

#include <gtest/gtest.h>

namespace bb::test::fuzz {

namespace fs = std::filesystem;

// Mutants per seed file: BB_FUZZ_ITERATIONS when it is a positive number (to look harder), else `fallback`.
inline int iterations(int fallback) {
  if (const char* s = std::getenv("BB_FUZZ_ITERATIONS"); s && std::atoi(s) > 0) return std::atoi(s);
  return fallback;
}

inline std::string read_file(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

inline void write_file(const fs::path& p, const std::string& bytes) {
  std::ofstream(p, std::ios::binary | std::ios::trunc) << bytes;
}

// An empty folder `name` in the temporary folder (one per seed: ctest runs the tests at once).
inline fs::path fresh_dir(const std::string& name) {
  const fs::path d = fs::temp_directory_path() / name;
  fs::remove_all(d);
  fs::create_directories(d);
  return d;
}

// The shared data folder `sub` (../shared/data/<sub> beside the clone: real models and clips; may be absent).
inline fs::path shared_dir(const std::string& sub) { return fs::path(BB_SHARED_DATA_DIR) / sub; }

// Those of the files `names` that are in `dir`.
inline std::vector<fs::path> present(const fs::path& dir, std::initializer_list<const char*> names) {
  std::vector<fs::path> out;
  for (const char* n : names)
    if (fs::exists(dir / n)) out.push_back(dir / n);
  return out;
}

// BB_FUZZ_SEED when it is a positive number: mixed into every test's own seeds, so that a longer campaign
// draws streams that CI's runs never drew (0 or unset: the tests' seeds as they are).
inline std::uint32_t seed_offset() {
  const char* s = std::getenv("BB_FUZZ_SEED");
  if (s == nullptr) return 0;
  const unsigned long v = std::strtoul(s, nullptr, 10);
  return static_cast<std::uint32_t>(v);
}

// Seeded, so that a run repeats itself (with the same BB_FUZZ_SEED). The fuzz tests' mutators derive from it.
class Random {
 public:
  explicit Random(std::uint32_t seed)
      : rng_(seed_offset() == 0 ? seed : seed ^ (seed_offset() * 0x9E3779B9u + 0x7F4A7C15u)) {}

  // In [0, n); 0 when n is 0.
  std::size_t below(std::size_t n) { return n == 0 ? 0 : std::uniform_int_distribution<std::size_t>(0, n - 1)(rng_); }
  bool chance(int percent) { return static_cast<int>(below(100)) < percent; }
  template <class T, std::size_t N>
  const T& pick(const T (&a)[N]) { return a[below(N)]; }
  template <class T>
  const T& pick(const std::vector<T>& v) { return v[below(v.size())]; }  // `v` must not be empty

 private:
  std::mt19937 rng_;
};

// ---- text and bytes -----------------------------------------------------------------------------------

// A part of a text: `n` characters from `at`.
struct Span {
  std::size_t at, n;
};

// Puts the text of `a` where `b` is and the other way round (the later one first, so that the earlier offset
// stays valid). The spans must not overlap; nothing happens when they are the same.
inline void swap_spans(std::string& t, Span a, Span b) {
  if (a.at > b.at) std::swap(a, b);
  if (a.at == b.at) return;
  const std::string ta = t.substr(a.at, a.n), tb = t.substr(b.at, b.n);
  t.replace(b.at, b.n, ta);
  t.replace(a.at, a.n, tb);
}

// One bit of `b` (not empty) flipped.
inline void flip_bit(Random& r, std::string& b) { b[r.below(b.size())] ^= static_cast<char>(1u << r.below(8)); }

// Byte-level damage anywhere in `b`: a bit flipped, a byte replaced (half the time by one of `specials`, when
// given, else by any byte), the end cut off, up to 64 bytes deleted or copied to another place. An empty `b`
// becomes `fill`.
inline void damage_bytes(Random& r, std::string& b, char fill, std::string_view specials = {}) {
  if (b.empty()) return b.push_back(fill);
  auto range = [&] {
    const std::size_t at = r.below(b.size());
    return Span{at, 1 + r.below(std::min<std::size_t>(64, b.size() - at))};
  };
  switch (r.below(5)) {
    case 0: flip_bit(r, b); break;
    case 1: {
      const std::size_t at = r.below(b.size());
      b[at] = !specials.empty() && r.chance(50) ? specials[r.below(specials.size())] : static_cast<char>(r.below(256));
      break;
    }
    case 2: b.resize(r.below(b.size())); break;  // cut short
    case 3: {
      const Span s = range();
      b.erase(s.at, s.n);
      break;
    }
    default: {
      const Span s = range();
      b.insert(r.below(b.size() + 1), b.substr(s.at, s.n));
    }
  }
}

// Number texts that break parsers (not all valid JSON): zero and signs, 32- and 64-bit limits and one past
// them, huge, tiny, out of double's range, not finite, too long.
inline constexpr const char* kNumberTexts[] = {
    "0", "-1", "1", "2", "-0", "1e30", "-1e30", "nan", "NaN", "inf", "-inf", "1e-45", "1e308", "1e400",
    "4294967295", "4294967296", "2147483647", "2147483648", "-2147483648",
    "18446744073709551615", "99999999999999999999999"};

// kNumberTexts and a format's own troublesome numbers.
inline std::vector<const char*> number_texts(std::initializer_list<const char*> own) {
  std::vector<const char*> v(std::begin(kNumberTexts), std::end(kNumberTexts));
  v.insert(v.end(), own);
  return v;
}

// ---- JSON text ----------------------------------------------------------------------------------------

struct Token {
  Span span;
  bool number;
};

// The tokens of a JSON text: strings, numbers, punctuation, words (true, null, and what damage left).
inline std::vector<Token> json_tokens(const std::string& t) {
  std::vector<Token> toks;
  for (std::size_t i = 0; i < t.size();) {
    const char ch = t[i];
    if (ch == '"') {
      std::size_t e = i + 1;
      while (e < t.size() && t[e] != '"') e += t[e] == '\\' ? 2 : 1;
      e = std::min(e + 1, t.size());
      toks.push_back({{i, e - i}, false});
      i = e;
    } else if (ch == '-' || (ch >= '0' && ch <= '9')) {
      std::size_t e = i + 1;
      while (e < t.size() && t[e] && std::strchr("0123456789.eE+-", t[e])) ++e;
      toks.push_back({{i, e - i}, true});
      i = e;
    } else if (ch && std::strchr("{}[],:", ch)) {
      toks.push_back({{i, 1}, false});
      ++i;
    } else if (std::isalpha(static_cast<unsigned char>(ch))) {
      std::size_t e = i;
      while (e < t.size() && std::isalpha(static_cast<unsigned char>(t[e]))) ++e;
      toks.push_back({{i, e - i}, false});
      i = e;
    } else {
      ++i;
    }
  }
  return toks;
}

// Token-level damage of a JSON text that keeps the tokens apart: a number replaced by one of `numbers` (60% of
// the time, when there is a number), else two tokens swapped. False, with `t` untouched, when `t` has fewer
// than two tokens (the caller damages its bytes instead).
inline bool damage_json_tokens(Random& r, std::string& t, const std::vector<const char*>& numbers) {
  const std::vector<Token> toks = json_tokens(t);
  if (toks.size() < 2) return false;
  if (r.chance(60)) {
    std::vector<Span> nums;
    for (const Token& k : toks)
      if (k.number) nums.push_back(k.span);
    if (!nums.empty()) {
      const Span k = r.pick(nums);
      t.replace(k.at, k.n, r.pick(numbers));
      return true;
    }
  }
  const Span a = r.pick(toks).span, b = r.pick(toks).span;
  swap_spans(t, a, b);
  return true;
}

// A value (0) nested 1000 or 100000 arrays or objects ({"a": ...}) deep, for a JSON parser's recursion.
inline std::string deep_value(Random& r) {
  const std::size_t depth = r.chance(50) ? 1000 : 100000;
  const bool arrays = r.chance(50);
  std::string deep;
  for (std::size_t d = 0; d < depth; ++d) deep += arrays ? "[" : "{\"a\":";
  deep += "0";
  for (std::size_t d = 0; d < depth; ++d) deep += arrays ? "]" : "}";
  return deep;
}

// ---- JSON documents (templates over nlohmann::json, so that this header need not include it) ----------

// The places of a document that a structure-aware edit may aim at: all but the root, and the hot ones, under a
// key of `hot_keys` (array elements inherit their array's key).
template <class Json>
class Sites {
 public:
  using Pointer = typename Json::json_pointer;
  std::vector<Pointer> all, hot;

  Sites(const Json& doc, const std::set<std::string>& hot_keys) { collect(doc, Pointer(), "", hot_keys); }

  // A hot place 70% of the time (when there is one), else any. `all` must not be empty.
  const Pointer& pick(Random& r) const { return !hot.empty() && r.chance(70) ? r.pick(hot) : r.pick(all); }

 private:
  void collect(const Json& j, const Pointer& p, const std::string& key, const std::set<std::string>& hot_keys) {
    if (!p.empty()) {
      all.push_back(p);
      if (hot_keys.count(key)) hot.push_back(p);
    }
    if (j.is_object()) {
      for (auto it = j.begin(); it != j.end(); ++it) collect(it.value(), p / it.key(), it.key(), hot_keys);
    } else if (j.is_array()) {
      for (std::size_t i = 0; i < j.size(); ++i) collect(j[i], p / i, key, hot_keys);
    }
  }
};

// Whether `inner` is `outer` or inside it.
template <class Json>
bool contains(const Json& outer, const Json& inner) {
  if (&outer == &inner) return true;
  if (outer.is_structured())
    for (const Json& e : outer)
      if (contains(e, inner)) return true;
  return false;
}

// The value at `p` (not the root) removed from its object or array.
template <class Json>
void erase_at(Json& doc, const typename Json::json_pointer& p) {
  Json& parent = doc[p.parent_pointer()];
  if (parent.is_object()) parent.erase(p.back());
  else if (parent.is_array() && !parent.empty()) parent.erase(parent.begin() + std::stoi(p.back()));
}

// `v`, a value in `doc`, swapped with the value at another of `sites` (unless one holds the other).
template <class Json>
void swap_with_another(Random& r, Json& doc, Json& v, const Sites<Json>& sites) {
  Json& w = doc[r.pick(sites.all)];
  if (&w != &v && !contains(v, w) && !contains(w, v)) std::swap(v, w);
}

// ---- the run ------------------------------------------------------------------------------------------

// For `run`: an accepted mutant needs nothing more than to have loaded.
struct Loaded {
  template <class T>
  std::string operator()(const T&) const {
    return {};
  }
};

// Writes `seed` to `path` and checks that it loads, then writes `count` mutants (`mutant()` gives the next one's
// bytes) to `path` one after another and loads each with `load(path)`, which returns a bb::Result. An accepted
// mutant must pass `valid(value)` (which says what is wrong, or returns ""); a rejected one's error must name
// `path`, a place in it and a reason. The first failing mutant is kept beside `path` as failing_<i>_<file name>,
// reported with ADD_FAILURE, and ends the run. Prints the tally and a few distinct errors; returns whether
// the seed and every mutant passed.
template <class Mutant, class Load, class Valid = Loaded>
bool run(const fs::path& path, const std::string& seed, int count, Mutant mutant, Load load, Valid valid = {}) {
  const std::string name = path.filename().string();
  write_file(path, seed);
  if (auto r = load(path.string()); !r.ok()) {
    ADD_FAILURE() << "the seed " << name << " does not load: " << r.error().message();
    return false;
  }
  int accepted = 0, rejected = 0;
  std::vector<std::string> samples;  // a few error messages with distinct reasons
  std::set<std::string> seen;
  bool passed = true;
  for (int i = 0; i < count && passed; ++i) {
    const std::string text = mutant();
    write_file(path, text);
    auto r = load(path.string());
    std::string problem;
    if (r.ok()) {
      ++accepted;
      problem = valid(*r);
    } else {
      ++rejected;
      const std::string msg = r.error().message();
      if (msg.find(path.string()) == std::string::npos || r.error().where.empty() || r.error().reason.empty())
        problem = "the error does not name the file, a place and a reason: " + msg;
      else if (samples.size() < 4 && seen.insert(r.error().reason.substr(0, 32)).second)
        samples.push_back(msg.substr(0, 240));
    }
    if (!problem.empty()) {  // the first failing mutant of a seed is enough to look at
      const fs::path keep = path.parent_path() / ("failing_" + std::to_string(i) + "_" + name);
      write_file(keep, text);
      ADD_FAILURE() << name << " mutant " << i << " (kept as " << keep.string() << "; BB_FUZZ_SEED=" << seed_offset()
                    << "): " << problem;
      passed = false;
    }
  }
  std::cout << "[fuzz] " << name << ": " << accepted + rejected << " mutants, " << accepted << " accepted, "
            << rejected << " rejected" << (seed_offset() ? ", BB_FUZZ_SEED=" + std::to_string(seed_offset()) : std::string())
            << "\n";
  for (const std::string& s : samples) std::cout << "[fuzz]   e.g. " << s << "\n";
  return passed;
}

}  // namespace bb::test::fuzz
