// Deterministic mutation fuzzing of the BVH reader (load_bvh: parse and retarget): hand-written clips
// (LF, and CRLF with tabs and other rotation orders) and the first frames of the shared CMU clips are
// mutated a few hundred times each (numbers replaced by troublesome ones, words and lines swapped,
// deleted, duplicated, keywords put in the wrong place, bytes damaged, the file cut short), every mutant
// is written to a file and loaded. Each load must return: a clip (with a finite, positive frame rate and
// finite postures), or an error that names the file, a line and a reason. BB_FUZZ_ITERATIONS=N sets
// the mutants per seed.
#include <cctype>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "bb/modeler/skeleton.h"
#include "bb/motion/bvh.h"
#include "fuzz.h"

namespace bb::motion {
namespace {

namespace fs = std::filesystem;
namespace fuzz = bb::test::fuzz;
using fuzz::Span;

// Legs on both sides (so that retargeting runs), a spine, an arm; 4 frames.
std::string hand_made(bool crlf) {
  const char* nl = crlf ? "\r\n" : "\n";
  std::string t;
  auto line = [&](int depth, const std::string& s) { t += std::string(depth, crlf ? '\t' : ' ') + s + nl; };
  line(0, "HIERARCHY");
  line(0, "ROOT Hips");
  line(0, "{");
  line(1, "OFFSET 0 0 0");
  line(1, crlf ? "CHANNELS 6 Xposition Yposition Zposition Yrotation Xrotation Zrotation"
               : "CHANNELS 6 Xposition Yposition Zposition Zrotation Yrotation Xrotation");
  int channels = 6;
  auto chain = [&](const char* const* names, int n, float x, float y0) {
    for (int k = 0; k < n; ++k) {
      line(1 + k, std::string("JOINT ") + names[k]);
      line(1 + k, "{");
      line(2 + k, "OFFSET " + std::to_string(k == 0 ? x : 0.0f) + " " + std::to_string(k == 0 ? y0 : -4.0f) + " 0.5");
      line(2 + k, crlf ? "CHANNELS 3 Xrotation Zrotation Yrotation" : "CHANNELS 3 Zrotation Xrotation Yrotation");
      channels += 3;
    }
    line(1 + n, "End Site");
    line(1 + n, "{");
    line(2 + n, "OFFSET 0 -1 1");
    line(1 + n, "}");
    for (int k = n - 1; k >= 0; --k) line(1 + k, "}");
  };
  const char* left_leg[] = {"LeftUpLeg", "LeftLeg", "LeftFoot"};
  const char* right_leg[] = {"RightUpLeg", "RightLeg", "RightFoot"};
  const char* spine[] = {"Spine", "Neck", "Head"};
  const char* arm[] = {"LeftArm", "LeftForeArm", "LeftHand"};
  chain(left_leg, 3, 1.0f, 0.0f);
  chain(right_leg, 3, -1.0f, 0.0f);
  chain(spine, 3, 0.0f, 3.0f);
  chain(arm, 3, 1.5f, 5.0f);
  line(0, "}");
  line(0, "MOTION");
  line(0, "Frames: 4");
  line(0, "Frame Time: 0.0333333");
  for (int f = 0; f < 4; ++f) {
    std::string values;
    for (int c = 0; c < channels; ++c) {
      if (c) values += ' ';
      values += std::to_string(c == 1 ? 9.0f + 0.1f * f : (c % 3 == 0 ? 10.0f * f - 5.0f : 2.5f * c / (f + 1)));
    }
    line(0, values);
  }
  return t;
}

// The hierarchy and the first `frames` frames of a BVH file (its "Frames:" count set to match).
std::string first_frames(const std::string& text, int frames) {
  const auto motion = text.find("MOTION");
  const auto count = text.find("Frames:", motion);
  const auto count_end = text.find('\n', count);
  const auto time_end = text.find('\n', count_end + 1);
  std::string out = text.substr(0, count) + "Frames: " + std::to_string(frames) +
                    (text[count_end - 1] == '\r' ? "\r" : "") + text.substr(count_end, time_end + 1 - count_end);
  std::size_t at = time_end + 1;
  for (int f = 0; f < frames && at < text.size(); ++f) {
    const auto e = text.find('\n', at);
    out += text.substr(at, e == std::string::npos ? std::string::npos : e + 1 - at);
    at = e == std::string::npos ? text.size() : e + 1;
  }
  return out;
}

// Numbers that trouble a BVH reader besides the common ones: channel counts, big frame counts, hexadecimal,
// a decimal comma, nothing at all, the float limits.
const std::vector<const char*> kNumberTexts = fuzz::number_texts(
    {"6", "7", "1e-39", "1e9", "100000000", "2.5", "0x10", "1,5", "", "3.4e38", "1e39", "0.0"});

class Mutator : public fuzz::Random {
 public:
  using Random::Random;

  void mutate(std::string& t) {
    switch (below(10)) {
      case 0:
      case 1:
      case 2: return number(t);
      case 3: return swap_words(t);
      case 4: return keyword(t);
      case 5:
      case 6: return lines(t);
      case 7: return whitespace(t);
      default: return bytes(t);
    }
  }

 private:
  static std::vector<Span> words(const std::string& t) {
    std::vector<Span> w;
    for (std::size_t i = 0; i < t.size();) {
      if (std::isspace(static_cast<unsigned char>(t[i]))) { ++i; continue; }
      std::size_t e = i;
      while (e < t.size() && !std::isspace(static_cast<unsigned char>(t[e]))) ++e;
      w.push_back({i, e - i});
      i = e;
    }
    return w;
  }
  static bool is_number(const std::string& s) {
    char* end = nullptr;
    std::strtod(s.c_str(), &end);
    return !s.empty() && end && *end == '\0';
  }

  // A number (an offset, a channel count, the frame count or time, a channel value) made troublesome.
  void number(std::string& t) {
    std::vector<Span> nums, counts;  // counts: the words after CHANNELS, Frames: and Time:
    const std::vector<Span> all = words(t);
    for (std::size_t k = 0; k < all.size(); ++k) {
      if (!is_number(t.substr(all[k].at, all[k].n))) continue;
      nums.push_back(all[k]);
      const std::string before = k ? t.substr(all[k - 1].at, all[k - 1].n) : "";
      if (before == "CHANNELS" || before == "Frames:" || before == "Time:") counts.push_back(all[k]);
    }
    if (nums.empty()) return bytes(t);
    // The counts are few and the values many: aim at a count now and then.
    const Span w = !counts.empty() && chance(35) ? pick(counts) : pick(nums);
    t.replace(w.at, w.n, pick(kNumberTexts));
  }

  void swap_words(std::string& t) {
    const std::vector<Span> w = words(t);
    if (w.size() < 2) return bytes(t);
    const Span a = pick(w), b = pick(w);
    fuzz::swap_spans(t, a, b);
  }

  void keyword(std::string& t) {
    std::vector<Span> w = words(t);
    if (w.empty()) return bytes(t);
    const char* const keys[] = {"ROOT",   "JOINT",  "End",      "Site",      "{",         "}",      "OFFSET",
                                "CHANNELS", "MOTION", "Frames:", "Frame",    "Time:",     "HIERARCHY", "Xrotation",
                                "Zposition", "End Site", "{ }",  "} }",      "JOINT X {", "Qrotation"};
    const Span x = pick(w);
    if (chance(50)) t.replace(x.at, x.n, pick(keys));
    else t.insert(x.at, std::string(pick(keys)) + " ");
  }

  // Whole lines deleted, duplicated, swapped, or a block of lines repeated (a joint twice, frames twice).
  void lines(std::string& t) {
    std::vector<std::size_t> starts{0};
    for (std::size_t i = 0; i < t.size(); ++i)
      if (t[i] == '\n' && i + 1 < t.size()) starts.push_back(i + 1);
    auto line_at = [&](std::size_t k) {
      const std::size_t e = k + 1 < starts.size() ? starts[k + 1] : t.size();
      return Span{starts[k], e - starts[k]};
    };
    const std::size_t k = below(starts.size());
    const Span line = line_at(k);
    switch (below(4)) {
      case 0: t.erase(line.at, line.n); break;
      case 1: t.insert(line.at, t.substr(line.at, line.n)); break;
      case 2: fuzz::swap_spans(t, line, line_at(below(starts.size()))); break;
      default: {
        const Span last = line_at(std::min(starts.size() - 1, k + 1 + below(12)));
        const std::string block = t.substr(line.at, last.at + last.n - line.at);
        for (std::size_t r = 1 + below(3); r > 0; --r) t.insert(line.at, block);
      }
    }
  }

  void whitespace(std::string& t) {
    std::vector<std::size_t> spaces;
    for (std::size_t i = 0; i < t.size(); ++i)
      if (std::isspace(static_cast<unsigned char>(t[i]))) spaces.push_back(i);
    if (spaces.empty()) return bytes(t);
    const char subs[] = {' ', '\n', '\r', '\t', '\0', '\v', '\f'};
    const std::size_t at = pick(spaces);
    if (chance(70)) t[at] = pick(subs);
    else t.erase(at, 1);  // two words run together
  }

  void bytes(std::string& t) { fuzz::damage_bytes(*this, t, 'H'); }
};

// An accepted clip has a finite, positive frame rate, frames, and finite postures; returns what is wrong, or "".
std::string check_clip(const Clip& clip) {
  bool finite = true;
  for (const auto& p : clip.frames)
    for (float v : p) finite &= std::isfinite(v);
  if (!(std::isfinite(clip.fps) && clip.fps > 0)) return "frame rate " + std::to_string(clip.fps);
  if (clip.frames.empty()) return "no frames";
  if (!finite) return "a posture is not finite";
  return {};
}

void fuzz_bvh(const std::string& name, const std::string& seed, std::uint32_t rng_seed, int count) {
  const modeler::Skeleton& sk = modeler::default_skeleton();
  const fs::path dir = fuzz::fresh_dir("bb_bvh_fuzz_" + name);
  Mutator m(rng_seed);
  auto mutant = [&] {
    std::string text = seed;
    for (int e = 1 + static_cast<int>(m.below(3)); e > 0; --e) m.mutate(text);
    return text;
  };
  auto load = [&](const std::string& path) { return load_bvh(path, sk); };
  if (fuzz::run(dir / (name + ".bvh"), seed, count, mutant, load, check_clip)) fs::remove_all(dir);
}

TEST(BvhFuzz, HandMadeClips) {
  fuzz_bvh("hand_lf", hand_made(false), 1301u, fuzz::iterations(1500));
  fuzz_bvh("hand_crlf", hand_made(true), 1302u, fuzz::iterations(1500));
}

TEST(BvhFuzz, SharedCmuClips) {
  const fs::path dir = fuzz::shared_dir("bvh");
  if (!fs::exists(dir)) GTEST_SKIP() << "shared data absent: " << dir << " (only the hand-made clips were fuzzed)";
  std::uint32_t rng_seed = 1401;
  for (const fs::path& p : fuzz::present(dir, {"131_01.bvh", "01_01.bvh"}))
    // The hierarchy and a few frames: the parser and retargeting see everything the file has, fast.
    fuzz_bvh(p.stem().string(), first_frames(fuzz::read_file(p), 6), rng_seed++, fuzz::iterations(1000));
}

}  // namespace
}  // namespace bb::motion
