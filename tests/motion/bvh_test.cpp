#include <cmath>
#include <cstring>
#include <map>
#include <filesystem>
#include <fstream>
#include <sstream>

#include <gtest/gtest.h>

#include "bb/modeler/body.h"
#include "bb/motion/bvh.h"

using namespace bb;

namespace {

const char* kTiny =
    "HIERARCHY\r\n"
    "ROOT Hips\r\n{\r\n\tOFFSET 0 0 0\r\n\tCHANNELS 6 Xposition Yposition Zposition Zrotation Yrotation Xrotation\r\n"
    "\tJOINT LeftUpLeg\r\n\t{\r\n\t\tOFFSET 1 0 0\r\n\t\tCHANNELS 3 Zrotation Xrotation Yrotation\r\n"
    "\t\tEnd Site\r\n\t\t{\r\n\t\t\tOFFSET 0 -2 0\r\n\t\t}\r\n\t}\r\n}\r\n"
    "MOTION\r\nFrames: 2\r\nFrame Time: 0.5\r\n"
    "0 3 0 0 0 0 0 0 0\r\n"
    "1 3 0 0 90 0 0 45 0\r\n";

std::string data(const char* name) { return std::string(BB_SHARED_DATA_DIR) + "/bvh/" + name; }

}  // namespace

TEST(Bvh, ParsesCrlfAndPerJointRotationOrders) {
  auto r = motion::parse_bvh(kTiny, "tiny.bvh");
  ASSERT_TRUE(r) << r.error().message();
  ASSERT_EQ(r->joints.size(), 3u);  // Hips, LeftUpLeg, its end site
  EXPECT_EQ(r->joints[1].name, "LeftUpLeg");
  EXPECT_EQ(r->joints[1].parent, 0);
  EXPECT_TRUE(r->joints[2].end_site);
  EXPECT_EQ(r->channel_count, 9);
  EXPECT_EQ(r->joints[1].channels, (std::vector<int>{5, 3, 4}));  // Z, X, Y
  EXPECT_FLOAT_EQ(r->frame_time, 0.5f);
  ASSERT_EQ(r->frames.size(), 2u);
  EXPECT_FLOAT_EQ(r->frames[1][4], 90.0f);
  EXPECT_FLOAT_EQ(r->frames[1][7], 45.0f);
}

struct BadBvh {
  std::string text, where, reason;
};

TEST(Bvh, MalformedFilesNameTheLineAndReason) {
  std::string t = kTiny;
  std::vector<BadBvh> cases = {
      {"HIERARCHY\nROOT Hips\n{\nOFFSET 0 0\n", "line 4", "expected a number"},
      {std::string(t).replace(t.find("Zrotation Xrotation Yrotation"), 9, "Qrotation"), "line 9", "unknown channel"},
      {std::string(t).replace(t.find("CHANNELS 3"), 10, "CHANNELS 9"), "line 9", "0..6"},
      {t.substr(0, t.rfind("1 3 0 0 90")), "line 20", "truncated"},
      {std::string(t).replace(t.find("0 3 0 0 0 0 0 0 0"), 17, "0 3 0 0 0 0 0 0 0 7"), "line 19", "frame 1 has 10 values, expected 9"},
      {std::string(t).replace(t.find("MOTION"), 6, "MOTON"), "line 16", "expected MOTION"},
      {std::string(t).replace(t.find("0 3 0 0 0 0 0 0 0"), 1, "x"), "line 19", "expected a number"},
  };
  for (const auto& c : cases) {
    auto r = motion::parse_bvh(c.text, "bad.bvh");
    ASSERT_FALSE(r) << c.reason;
    EXPECT_EQ(r.error().file, "bad.bvh");
    EXPECT_EQ(r.error().where, c.where) << r.error().message();
    EXPECT_NE(r.error().reason.find(c.reason), std::string::npos) << r.error().message();
  }
  auto missing = motion::load_bvh("/nonexistent.bvh", modeler::default_skeleton());
  ASSERT_FALSE(missing);
  EXPECT_NE(missing.error().message().find("/nonexistent.bvh"), std::string::npos);
}

// Found in an audit: a UTF-8 byte order mark (some Windows editors write one) was "expected HIERARCHY at the start".
TEST(Bvh, AcceptsAUtf8ByteOrderMark) {
  auto r = motion::parse_bvh(std::string("\xEF\xBB\xBF") + kTiny, "bom.bvh");
  ASSERT_TRUE(r) << r.error().message();
  EXPECT_EQ(r->joints.size(), 3u);
  EXPECT_EQ(r->channel_count, 9);
  ASSERT_EQ(r->frames.size(), 2u);
  EXPECT_EQ(r->frames[1], (std::vector<float>{1, 3, 0, 0, 90, 0, 0, 45, 0}));
  // Only at the start: elsewhere its bytes are a word like any other.
  std::string t = kTiny;
  auto late = motion::parse_bvh(t.replace(t.find("ROOT"), 0, "\xEF\xBB\xBF"), "bom.bvh");
  ASSERT_FALSE(late);
  EXPECT_EQ(late.error().where, "line 2");
}

// Found in an audit: frame values were read as one stream, so a short row took its missing values from the next
// row and shifted every later frame's channels (accepted outright where "Frames:" was lower than the row count, or
// reported as the end of the file), and a frame wrapped over two lines was accepted. A frame is one line now.
TEST(Bvh, EachFrameIsOneLineOfExactlyTheChannelCount) {
  std::string t = kTiny;
  auto with = [&](std::string text, const char* from, const char* to) {
    return text.replace(text.find(from), std::strlen(from), to);
  };
  const std::string short_row = with(t, "0 3 0 0 0 0 0 0 0\r\n", "0 3 0 0 0 0 0 0\r\n");
  std::vector<BadBvh> cases = {
      {short_row, "line 19", "frame 1 has 8 values, expected 9"},
      {with(short_row, "Frames: 2", "Frames: 1"), "line 19", "frame 1 has 8 values, expected 9"},
      {with(t, "0 0 90 0 0 45 0\r\n", "0 0 90 0 0 45\r\n"), "line 20", "frame 2 has 8 values, expected 9"},
      // Wrapped: 5 values, then 4 on the next line.
      {with(t, "0 3 0 0 0 0 0 0 0\r\n", "0 3 0 0 0\r\n0 0 0 0\r\n"), "line 19", "frame 1 has 5 values, expected 9"},
      // Two frames on one line.
      {with(t, "0 3 0 0 0 0 0 0 0\r\n", "0 3 0 0 0 0 0 0 0 "), "line 19", "frame 1 has 18 values, expected 9"},
      // The first frame on the "Frame Time:" line.
      {with(t, "Frame Time: 0.5\r\n", "Frame Time: 0.5 "), "line 18", "unexpected \"0\" after the frame time"},
  };
  for (const auto& c : cases) {
    auto r = motion::parse_bvh(c.text, "bad.bvh");
    ASSERT_FALSE(r) << c.reason << " was accepted";
    EXPECT_EQ(r.error().where, c.where) << r.error().message();
    EXPECT_NE(r.error().reason.find(c.reason), std::string::npos) << r.error().message();
  }
  // Blank lines between and after the rows, tabs and trailing spaces are no frames, and no errors.
  auto spaced = motion::parse_bvh(with(with(t, "0 0 0 0 0 0 0\r\n", "0 0 0 0 0 0 0 \t\r\n\r\n  \r\n"),
                                       "0 45 0\r\n", "0\t45 0\n\n \t\n"),
                                  "spaced.bvh");
  ASSERT_TRUE(spaced) << spaced.error().message();
  ASSERT_EQ(spaced->frames.size(), 2u);
  EXPECT_EQ(spaced->frames[0], (std::vector<float>{0, 3, 0, 0, 0, 0, 0, 0, 0}));
  EXPECT_EQ(spaced->frames[1], (std::vector<float>{1, 3, 0, 0, 90, 0, 0, 45, 0}));
  // The last row needs no line end.
  auto unended = motion::parse_bvh(t.substr(0, t.size() - 2), "unended.bvh");
  ASSERT_TRUE(unended) << unended.error().message();
  EXPECT_EQ(unended->frames[1][7], 45.0f);
}

// Found in an audit: rows beyond the "Frames:" count were dropped without a word.
TEST(Bvh, RowsBeyondTheFrameCountAreErrors) {
  std::string t = kTiny;
  auto one = motion::parse_bvh(std::string(t).replace(t.find("Frames: 2"), 9, "Frames: 1"), "extra.bvh");
  ASSERT_FALSE(one);
  EXPECT_EQ(one.error().where, "line 20");
  EXPECT_EQ(one.error().reason, "a frame beyond the 1 that \"Frames:\" declares");
  auto garbage = motion::parse_bvh(t + "\r\n\r\nend\r\n", "extra.bvh");
  ASSERT_FALSE(garbage);
  EXPECT_EQ(garbage.error().where, "line 23");
  EXPECT_EQ(garbage.error().reason, "a frame beyond the 2 that \"Frames:\" declares");
}

// Found in an audit: strtof stopped at a NUL byte inside a word, and the rest of the word was ignored.
TEST(Bvh, ANulByteInsideANumberIsAnError) {
  std::string t = kTiny;
  t.replace(t.find("90"), 2, std::string("9\0x", 3));
  auto r = motion::parse_bvh(t, "nul.bvh");
  ASSERT_FALSE(r);
  EXPECT_EQ(r.error().where, "line 20");
  EXPECT_NE(r.error().reason.find("expected a number for a channel value"), std::string::npos) << r.error().message();
}

// Found in an audit: a folder opens and reads as an empty file, "line 1: expected HIERARCHY at the start".
TEST(Bvh, ADirectoryIsNamedAsSuch) {
  const std::filesystem::path dir = std::filesystem::temp_directory_path() / "bb_bvh_test_folder.bvh";
  std::filesystem::create_directories(dir);
  auto r = motion::load_bvh(dir.string(), modeler::default_skeleton());
  std::filesystem::remove(dir);
  ASSERT_FALSE(r);
  EXPECT_EQ(r.error().file, dir.string());
  EXPECT_EQ(r.error().reason, "is a directory, not a BVH file");
}

// Found by bvh_fuzz_test.cpp and in the code it pointed at: counts that overflowed an int (undefined
// behaviour) or allocated what the file claimed (2e9 frames: 48 GB, then std::terminate), a frame count that
// nothing bounded (no channels: a hang), and offsets, values and frame times that gave NaN postures and an
// infinite frame rate. Now errors.
TEST(Bvh, DamagedCountsAndOutOfRangeNumbersAreErrors) {
  std::string t = kTiny;
  auto with = [&](std::string text, const char* from, const char* to) {
    return text.replace(text.find(from), std::strlen(from), to);
  };
  const std::string no_channels =
      with(with(t, "CHANNELS 6 Xposition Yposition Zposition Zrotation Yrotation Xrotation", "CHANNELS 0"),
           "CHANNELS 3 Zrotation Xrotation Yrotation", "CHANNELS 0");
  std::vector<BadBvh> cases = {
      {with(t, "Frames: 2", "Frames: 2000000000"), "line 21", "file ends before frame 3 of 2000000000"},
      {with(t, "Frames: 2", "Frames: 1e30"), "line 17", "frame count 1e30 is too large"},
      {with(t, "CHANNELS 3", "CHANNELS 1e30"), "line 9", "channel count must be 0..6, got 1e30"},
      {with(t, "CHANNELS 3", "CHANNELS 2.5"), "line 9", "channel count must be 0..6"},
      {with(no_channels, "Frames: 2", "Frames: 2000000000"), "line 16", "no joint has channels"},
      {with(t, "OFFSET 1 0 0", "OFFSET 1e30 0 0"), "line 8", "OFFSET 1e30 is out of range"},
      {with(t, "1 3 0 0 90", "1 3 0 0 1e30"), "line 20", "a channel value 1e30 is out of range"},
      {with(t, "Frame Time: 0.5", "Frame Time: 1e-45"), "line 18", "frame time must be from 1e-6 to 1e6 seconds"},
  };
  for (const auto& c : cases) {
    auto r = motion::parse_bvh(c.text, "bad.bvh");
    ASSERT_FALSE(r) << c.reason;
    EXPECT_EQ(r.error().where, c.where) << r.error().message();
    EXPECT_NE(r.error().reason.find(c.reason), std::string::npos) << r.error().message();
  }
}

TEST(Bvh, CmuClipsKeepTheirFramesAndRateAndWalk) {
  if (!std::filesystem::exists(data("131_01.bvh"))) GTEST_SKIP() << "../shared/data/bvh is absent";
  const auto& sk = modeler::default_skeleton();
  struct Expect { const char* file; size_t frames; } files[] = {{"131_01.bvh", 994}, {"01_01.bvh", 2752}};
  for (const auto& f : files) {
    auto clip = motion::load_bvh(data(f.file), sk);
    ASSERT_TRUE(clip) << clip.error().message();
    EXPECT_EQ(clip->frames.size(), f.frames);
    EXPECT_NEAR(clip->fps, 120.0f, 0.01f);
    EXPECT_NEAR(clip->duration(), (f.frames - 1) / 120.0f, 0.01f);
    for (const auto& p : clip->frames) ASSERT_TRUE(sk.within_limits(p));
  }
  // Retargeting: our thighs, shanks and upper arms point the way the captured bones point.
  auto text = [](const std::string& p) {
    std::ifstream in(p, std::ios::binary);
    std::stringstream ss;
    ss << in.rdbuf();
    return ss.str();
  };
  auto bvh = motion::parse_bvh(text(data("131_01.bvh")), "131_01.bvh");
  ASSERT_TRUE(bvh);
  auto clip = motion::retarget(*bvh, sk, "131_01");
  ASSERT_TRUE(clip);
  auto idx = [&](const char* n) {
    for (size_t i = 0; i < bvh->joints.size(); ++i)
      if (bvh->joints[i].name == n) return static_cast<int>(i);
    return -1;
  };
  struct Bone { const char *a, *b, *ours_a, *ours_b; } bones[] = {
      {"LeftHip", "LeftKnee", "l_hip", "l_knee"},     {"LeftKnee", "LeftAnkle", "l_knee", "l_ankle"},
      {"RightHip", "RightKnee", "r_hip", "r_knee"},   {"RightKnee", "RightAnkle", "r_knee", "r_ankle"},
      {"LeftShoulder", "LeftElbow", "l_shoulder", "l_elbow"}};
  for (const auto& bone : bones) {
    int within = 0, n = 0;
    for (size_t f = 0; f < clip->frames.size(); f += 10, ++n) {
      auto p = motion::world_positions(*bvh, f);
      glm::vec3 d = glm::normalize(p[idx(bone.b)] - p[idx(bone.a)]);
      auto w = sk.world_transforms(clip->frames[f]);
      glm::vec3 o = glm::normalize(glm::vec3(w[sk.find_joint(bone.ours_b)][3] - w[sk.find_joint(bone.ours_a)][3]));
      within += glm::dot(d, o) > std::cos(glm::radians(20.0f));
    }
    // Some captured poses lie beyond our joint limits (the knee has one DOF): 80 % is the bar.
    EXPECT_GT(within, n * 8 / 10) << bone.a;
  }
  // The body travels (the root follows the hips, scaled).
  auto first = sk.world_transforms(clip->frames.front()), last = sk.world_transforms(clip->frames.back());
  EXPECT_GT(glm::length(glm::vec3(last[0][3] - first[0][3])), 1.0f);
}

namespace {

// The file's text with its joints renamed (names not in `map` keep theirs; `prefix` goes before
// every name), as another convention would name them.
std::string renamed(const std::string& text, const std::map<std::string, std::string>& map,
                    const std::string& prefix = "") {
  std::istringstream in(text);
  std::string out, line;
  while (std::getline(in, line)) {
    size_t k = line.find_first_not_of(" \t");
    for (const char* key : {"ROOT ", "JOINT "}) {
      if (k == std::string::npos || line.compare(k, std::strlen(key), key) != 0) continue;
      size_t b = k + std::strlen(key), e = line.find_first_of(" \t\r", b);
      std::string name = line.substr(b, e == std::string::npos ? std::string::npos : e - b);
      auto it = map.find(name);
      line = line.substr(0, b) + prefix + (it == map.end() ? name : it->second) +
             (e == std::string::npos ? "" : line.substr(e));
    }
    out += line + "\n";
  }
  return out;
}

}  // namespace

TEST(Bvh, OtherJointNamingsRetargetTheSame) {
  if (!std::filesystem::exists(data("01_01.bvh"))) GTEST_SKIP() << "../shared/data/bvh is absent";
  const auto& sk = modeler::default_skeleton();
  std::ifstream in(data("01_01.bvh"), std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  const std::string text = ss.str();
  auto reference = motion::parse_bvh(text, "01_01.bvh");
  ASSERT_TRUE(reference);
  auto ref = motion::retarget(*reference, sk, "01_01");
  ASSERT_TRUE(ref) << ref.error().message();
  // The same capture as the Daz-friendly release, the original ASF skeleton and Mixamo name it:
  // every role lands on the same captured joint, so the clip is the same, value for value.
  std::map<std::string, std::string> daz = {
      {"Hips", "hip"}, {"LowerBack", "abdomen"}, {"Spine", "chest"}, {"Neck", "neck"}, {"Head", "head"},
      {"LeftShoulder", "lCollar"}, {"LeftArm", "lShldr"}, {"LeftForeArm", "lForeArm"}, {"LeftHand", "lHand"},
      {"LeftFingerBase", "lMid1"}, {"LeftUpLeg", "lThigh"}, {"LeftLeg", "lShin"}, {"LeftFoot", "lFoot"},
      {"LeftToeBase", "lToe"}, {"RightShoulder", "rCollar"}, {"RightArm", "rShldr"}, {"RightForeArm", "rForeArm"},
      {"RightHand", "rHand"}, {"RightFingerBase", "rMid1"}, {"RightUpLeg", "rThigh"}, {"RightLeg", "rShin"},
      {"RightFoot", "rFoot"}, {"RightToeBase", "rToe"}};
  std::map<std::string, std::string> asf = {
      {"Hips", "root"}, {"LowerBack", "lowerback"}, {"Spine", "thorax"}, {"Spine1", "upperback"},
      {"Neck", "lowerneck"}, {"Neck1", "upperneck"}, {"Head", "head"}, {"LeftShoulder", "lclavicle"},
      {"LeftArm", "lhumerus"}, {"LeftForeArm", "lradius"}, {"LeftHand", "lwrist"}, {"LeftFingerBase", "lhand"},
      {"LeftUpLeg", "lfemur"}, {"LeftLeg", "ltibia"}, {"LeftFoot", "lfoot"}, {"LeftToeBase", "ltoes"},
      {"RightShoulder", "rclavicle"}, {"RightArm", "rhumerus"}, {"RightForeArm", "rradius"}, {"RightHand", "rwrist"},
      {"RightFingerBase", "rhand"}, {"RightUpLeg", "rfemur"}, {"RightLeg", "rtibia"}, {"RightFoot", "rfoot"},
      {"RightToeBase", "rtoes"}, {"LFingers", "lfingers"}, {"RFingers", "rfingers"}};
  struct Variant { const char* name; std::string text; } variants[] = {
      {"daz", renamed(text, daz)}, {"asf", renamed(text, asf)}, {"mixamo", renamed(text, {}, "mixamorig:")}};
  for (const auto& v : variants) {
    auto bvh = motion::parse_bvh(v.text, v.name);
    ASSERT_TRUE(bvh) << bvh.error().message();
    auto clip = motion::retarget(*bvh, sk, "01_01");
    ASSERT_TRUE(clip) << v.name << ": " << clip.error().message();
    ASSERT_EQ(clip->frames.size(), ref->frames.size()) << v.name;
    EXPECT_EQ(clip->fps, ref->fps);
    size_t differing = 0;
    for (size_t f = 0; f < ref->frames.size(); ++f) differing += clip->frames[f] != ref->frames[f];
    EXPECT_EQ(differing, 0u) << v.name;
  }
  // A skeleton whose legs match no convention is refused with the file, the place and the reason.
  auto odd = motion::parse_bvh(renamed(text, {{"LeftUpLeg", "Oberschenkel_L"}, {"RightUpLeg", "Oberschenkel_R"}}),
                               "odd.bvh");
  ASSERT_TRUE(odd);
  auto refused = motion::retarget(*odd, sk, "odd", "odd.bvh");
  ASSERT_FALSE(refused);
  EXPECT_NE(refused.error().message().find("odd.bvh"), std::string::npos);
  EXPECT_NE(refused.error().message().find("unknown joint naming"), std::string::npos);
}
