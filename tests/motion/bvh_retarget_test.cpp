// Retargeting of the real CMU clips, checked against the source by forward kinematics: bone directions,
// feet against the floor. Found in an audit: an actor facing -Z got straight legs and feet pointing down
// (01_01, t = 9-17 s; toe tips 0.20 m below the floor), and standing clips floated 7-13 cm above it.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "bb/modeler/body.h"
#include "bb/motion/bvh.h"

using namespace bb;

namespace {

std::string data(const char* name) { return std::string(BB_SHARED_DATA_DIR) + "/bvh/" + name; }

std::string text_of(const std::string& p) {
  std::ifstream in(p, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

// One bone: its BVH start and end joints (either convention's name) and ours.
struct Bone {
  const char* what;
  std::vector<const char*> from, to;
  const char *ours_from, *ours_to;
};
const std::vector<Bone>& bones() {
  static const std::vector<Bone> b = {
      {"l thigh", {"LeftUpLeg", "LeftHip"}, {"LeftLeg", "LeftKnee"}, "l_hip", "l_knee"},
      {"r thigh", {"RightUpLeg", "RightHip"}, {"RightLeg", "RightKnee"}, "r_hip", "r_knee"},
      {"l shin", {"LeftLeg", "LeftKnee"}, {"LeftFoot", "LeftAnkle"}, "l_knee", "l_ankle"},
      {"r shin", {"RightLeg", "RightKnee"}, {"RightFoot", "RightAnkle"}, "r_knee", "r_ankle"},
      {"l foot", {"LeftFoot", "LeftAnkle"}, {"LeftToeBase", "LeftToe"}, "l_ankle", "l_metatarsophalangeal"},
      {"r foot", {"RightFoot", "RightAnkle"}, {"RightToeBase", "RightToe"}, "r_ankle", "r_metatarsophalangeal"},
      {"l upper arm", {"LeftArm", "LeftShoulder"}, {"LeftForeArm", "LeftElbow"}, "l_shoulder", "l_elbow"},
      {"r upper arm", {"RightArm", "RightShoulder"}, {"RightForeArm", "RightElbow"}, "r_shoulder", "r_elbow"},
      {"l forearm", {"LeftForeArm", "LeftElbow"}, {"LeftHand", "LeftWrist"}, "l_elbow", "l_wrist"},
      {"r forearm", {"RightForeArm", "RightElbow"}, {"RightHand", "RightWrist"}, "r_elbow", "r_wrist"},
  };
  return b;
}

int bvh_index(const motion::BvhFile& bvh, const std::vector<const char*>& names) {
  for (const char* n : names)
    for (size_t i = 0; i < bvh.joints.size(); ++i)
      if (bvh.joints[i].name == n) return static_cast<int>(i);
  return -1;
}

struct Measures {
  std::vector<std::vector<float>> angle;  // per bone, per frame: degrees between ours and the source's
  std::vector<float> lowest;              // per frame: our lowest foot point (ankle, ball, toe tip), metres
  std::vector<char> feet_down;            // per frame: both the source's ankles are at its floor's height
  std::vector<char> standing;             // per frame: and its legs are nearly straight and upright
  std::vector<float> lift;                // per frame: our hips' height less the source's, scaled, metres
  // Per side (left, right), per frame: that foot is down in the source and its ankle is dorsiflexed
  // more than 20 degrees (the active, non-weight-bearing range): shin and foot closer than in its
  // rest pose.
  std::vector<char> crouch[2];
  // Per side, per frame: how much farther our ankle is bent from its rest angle (shin to foot,
  // neutral posture) than the source's from its rest pose's, degrees (positive: ours more
  // dorsiflexed).
  std::vector<float> ankle_bend[2];
};

Measures measure(const motion::BvhFile& bvh, const motion::Clip& clip, const modeler::Skeleton& sk) {
  Measures m;
  m.angle.resize(bones().size());
  std::vector<int> from, to, ofrom, oto;
  for (const Bone& b : bones()) {
    from.push_back(bvh_index(bvh, b.from));
    to.push_back(bvh_index(bvh, b.to));
    ofrom.push_back(sk.find_joint(b.ours_from));
    oto.push_back(sk.find_joint(b.ours_to));
  }
  const int feet[] = {sk.find_joint("l_ankle"), sk.find_joint("r_ankle"), sk.find_joint("l_metatarsophalangeal"),
                      sk.find_joint("r_metatarsophalangeal"), sk.find_joint("l_toe_tip"), sk.find_joint("r_toe_tip")};
  const int lankle = bvh_index(bvh, {"LeftFoot", "LeftAnkle"}), rankle = bvh_index(bvh, {"RightFoot", "RightAnkle"});
  // The angle between shin (ankle to knee) and foot (ankle to toe), degrees: the source's and ours.
  auto between = [](glm::vec3 a, glm::vec3 b) {
    return glm::degrees(
        std::acos(std::clamp(glm::dot(glm::normalize(a), glm::normalize(b)), -1.0f, 1.0f)));
  };
  auto ankle_angle = [&](const std::vector<glm::vec3>& p, int side) {
    return between(p[from[2 + side]] - p[to[2 + side]], p[to[4 + side]] - p[from[4 + side]]);
  };
  auto our_ankle_angle = [&](const std::vector<glm::mat4>& w, int side) {
    return between(glm::vec3(w[ofrom[2 + side]][3] - w[oto[2 + side]][3]),
                   glm::vec3(w[oto[4 + side]][3] - w[ofrom[4 + side]][3]));
  };
  // The source's floor: the height its lower ankle has in most frames (the median over the clip).
  std::vector<float> lower;
  for (size_t f = 0; f < bvh.frames.size(); ++f) {
    auto p = motion::world_positions(bvh, f);
    lower.push_back(std::min(p[lankle].y, p[rankle].y));
  }
  std::sort(lower.begin(), lower.end());
  const float src_floor = lower[lower.size() / 2];
  auto rest = motion::world_positions(bvh, bvh.frames.size());
  const float src_leg = glm::length(rest[from[0]] - rest[to[2]]);
  const auto neutral = sk.world_transforms(sk.neutral());
  const float scale = glm::length(glm::vec3(neutral[ofrom[0]][3] - neutral[oto[2]][3])) / src_leg;
  const float our_ankle = neutral[oto[2]][3].y;
  const float rest_ankle[2] = {ankle_angle(rest, 0), ankle_angle(rest, 1)};
  const float our_rest_ankle[2] = {our_ankle_angle(neutral, 0), our_ankle_angle(neutral, 1)};
  for (size_t f = 0; f < bvh.frames.size(); ++f) {
    auto p = motion::world_positions(bvh, f);
    auto w = sk.world_transforms(clip.frames[f]);
    for (size_t b = 0; b < bones().size(); ++b) {
      glm::vec3 d = glm::normalize(p[to[b]] - p[from[b]]);
      glm::vec3 o = glm::normalize(glm::vec3(w[oto[b]][3] - w[ofrom[b]][3]));
      m.angle[b].push_back(glm::degrees(std::acos(std::clamp(glm::dot(d, o), -1.0f, 1.0f))));
    }
    float low = 1e30f;
    for (int j : feet) low = std::min(low, w[j][3].y);
    m.lowest.push_back(low);
    // Standing: both knees nearly straight, both shins nearly upright, both ankles at the floor's height.
    bool straight = true;
    for (int b = 0; b < 2; ++b) {
      const glm::vec3 thigh = glm::normalize(p[to[b]] - p[from[b]]), shin = glm::normalize(p[to[b + 2]] - p[from[b + 2]]);
      straight = straight && glm::dot(thigh, shin) > std::cos(glm::radians(25.0f)) && -shin.y > std::cos(glm::radians(25.0f));
    }
    const bool down = std::abs(p[lankle].y - src_floor) < 0.03f * src_leg && std::abs(p[rankle].y - src_floor) < 0.03f * src_leg;
    m.feet_down.push_back(down);
    m.lift.push_back(0.5f * (w[ofrom[0]][3].y + w[ofrom[1]][3].y) -
                     ((0.5f * (p[from[0]].y + p[from[1]].y) - src_floor) * scale + our_ankle));
    m.standing.push_back(down && straight);
    for (int s = 0; s < 2; ++s) {
      const int ankle = s == 0 ? lankle : rankle;
      const float src_bend = rest_ankle[s] - ankle_angle(p, s);
      m.crouch[s].push_back(p[ankle].y - src_floor < 0.05f * src_leg && src_bend > 20.0f);
      m.ankle_bend[s].push_back((our_rest_ankle[s] - our_ankle_angle(w, s)) - src_bend);
    }
  }
  return m;
}

float share_within(const std::vector<float>& a, float deg) {
  return static_cast<float>(std::count_if(a.begin(), a.end(), [&](float x) { return x <= deg; })) / a.size();
}

struct Loaded {
  motion::BvhFile bvh;
  motion::Clip clip;
};
Loaded load(const char* file) {
  auto bvh = motion::parse_bvh(text_of(data(file)), file);
  EXPECT_TRUE(bvh) << bvh.error().message();
  auto clip = motion::retarget(*bvh, modeler::default_skeleton(), file);
  EXPECT_TRUE(clip) << clip.error().message();
  return {*bvh, *clip};
}

}  // namespace

// Found in an audit: the root's rotation was fitted by Gauss-Newton from the last frame, and where the actor
// turned to face -Z the gradient vanished at yaw 0: the hips' twist then clamped, the knee could not bend in
// the captured plane, and 01_01 crouched on straight legs with the feet pointing down (shins 61 degrees off).
TEST(BvhRetarget, BonesPointTheSourcesWayFacingAnyDirection) {
  if (!std::filesystem::exists(data("01_01.bvh"))) GTEST_SKIP() << "shared data absent: " << data("") << " (needs the CMU clips)";
  const auto& sk = modeler::default_skeleton();
  for (const char* file : {"01_01.bvh", "131_01.bvh"}) {
    const Loaded l = load(file);
    ASSERT_EQ(l.clip.frames.size(), l.bvh.frames.size());
    const Measures m = measure(l.bvh, l.clip, sk);
    for (size_t b = 0; b < bones().size(); ++b) {
      const auto& a = m.angle[b];
      double sum = 0;
      for (float x : a) sum += x;
      std::printf("%s %-12s mean %5.1f worst %5.1f deg, %5.1f %% within 10\n", file, bones()[b].what, sum / a.size(),
                  *std::max_element(a.begin(), a.end()), 100 * share_within(a, 10));
      const bool foot = b == 4 || b == 5;
      // Thighs, shins, upper arms and forearms: within 20 degrees on 97 % of the frames (the
      // elbows' limits cut a few). The feet have our narrower ankle (no turn-out of its own) and
      // are matched by their angle to the shin from the rest poses', not as a direction (at rest
      // CMU's foot bone is 101-104 degrees from the shin, ours 109; see the crouch test below):
      // within 30 degrees on 85 %.
      if (foot) {
        EXPECT_GE(share_within(a, 30), 0.85f) << file << " " << bones()[b].what;
      } else {
        EXPECT_GE(share_within(a, 20), 0.97f) << file << " " << bones()[b].what;
      }
    }
  }
  // 01_01 faces -Z from about 9 s to 17 s: the crouch there bends our knees as the source does.
  const Loaded l = load("01_01.bvh");
  const Measures m = measure(l.bvh, l.clip, sk);
  for (int b = 2; b < 4; ++b) {
    float worst = 0;
    for (size_t f = 9 * 120; f < 17 * 120; ++f) worst = std::max(worst, m.angle[b][f]);
    EXPECT_LT(worst, 10.0f) << bones()[b].what << " at 9-17 s";
  }
}

// Found in an audit: the root was placed at the BVH root's height scaled by the legs' ratio (CMU's
// root sits ~11 cm, scaled, above its hip joints, ours 4 cm), over a floor taken from the first
// frame's lower ankle (a glitch in CMU's first frames): standing in 01_01, our feet were 7-13 cm
// above the floor. And with the knees straight and the feet pointing down, toe tips went 0.20 m
// (01_01) and 0.42 m (131_01) below it. Then the feet, matched to CMU's foot bone as a direction,
// stood toes up: standing, the lowest foot point 3.0-3.9 cm (our flat foot's toe tip: 2 cm); with
// both feet down at most 4.3 and 4.0 cm. They keep the source's ankle angle from the rest pose
// now: 1.1-3.0 cm, at most 3.4 and 2.9 cm.
TEST(BvhRetarget, FeetStayOnTheFloorAndDoNotFloat) {
  if (!std::filesystem::exists(data("01_01.bvh"))) GTEST_SKIP() << "shared data absent: " << data("") << " (needs the CMU clips)";
  const auto& sk = modeler::default_skeleton();
  // In the neutral posture our toe tips, the lowest foot points, are 2 cm above the floor.
  for (const char* file : {"01_01.bvh", "131_01.bvh"}) {
    const Loaded l = load(file);
    const Measures m = measure(l.bvh, l.clip, sk);
    float lowest = 1e30f, down_highest = -1e30f, stand_lo = 1e30f, stand_hi = -1e30f;
    int down = 0, standing = 0;
    for (size_t f = 0; f < m.lowest.size(); ++f) {
      lowest = std::min(lowest, m.lowest[f]);
      if (m.feet_down[f]) down_highest = std::max(down_highest, m.lowest[f]), ++down;
      if (m.standing[f]) stand_lo = std::min(stand_lo, m.lowest[f]), stand_hi = std::max(stand_hi, m.lowest[f]), ++standing;
    }
    double lift = 0;
    for (float x : m.lift) lift += x;
    std::printf("%s hips above the source's (scaled): mean %.3f, %.3f..%.3f m\n", file, lift / m.lift.size(),
                *std::min_element(m.lift.begin(), m.lift.end()), *std::max_element(m.lift.begin(), m.lift.end()));
    std::printf("%s lowest foot point %.3f m; both feet down (%d frames): lowest foot point at most %.3f m\n", file,
                lowest, down, down_highest);
    if (standing > 0) std::printf("%s standing (%d frames): lowest foot point %.3f..%.3f m\n", file, standing, stand_lo, stand_hi);
    EXPECT_GT(lowest, -0.02f) << file << ": a foot goes below the floor";
    ASSERT_GT(down, 100) << file;
    EXPECT_LT(down_highest, 0.04f) << file << ": with both feet down in the source, ours float";
    if (standing > 0) {
      EXPECT_GT(stand_lo, -0.01f) << file;
      EXPECT_LT(stand_hi, 0.035f) << file << ": standing, our toes are up";
    }
  }
}

// A known leftover of the audit above: our ankle dorsiflexed 20 degrees (AAOS's active range), and
// where the actor crouches on flat feet (01_01: 1409 foot-frames with an ankle more than 20 degrees
// past its rest angle, up to 42; 131_01: 320, up to 45) ours stopped there and tipped the toes into
// the floor: the ankle 8.2 and 5.7 degrees off the source's bend on average (worst 21.6, 23.7), the
// heel up, the body lifted up to 3.7 cm. The limit is the weight-bearing range now (45 degrees,
// data/skeleton.json), and the foot is retargeted from the rest poses' ankle angle (at rest CMU's
// foot bone is 101-104 degrees from the shin, ours 109; matched as a direction, ours stayed 6
// degrees more bent once the limit allowed): 1.1 and 1.5 degrees off on average (worst 8.3, 13.4),
// the hips lifted 0 and 2 mm on average.
TEST(BvhRetarget, CrouchingAnklesBendLikeTheSources) {
  if (!std::filesystem::exists(data("01_01.bvh")))
    GTEST_SKIP() << "shared data absent: " << data("") << " (needs the CMU clips)";
  const auto& sk = modeler::default_skeleton();
  for (const char* file : {"01_01.bvh", "131_01.bvh"}) {
    const Loaded l = load(file);
    const Measures m = measure(l.bvh, l.clip, sk);
    std::vector<float> ankle, shin;
    double lift = 0;
    float lift_worst = 0;
    for (int s = 0; s < 2; ++s)
      for (size_t f = 0; f < m.crouch[s].size(); ++f) {
        if (!m.crouch[s][f]) continue;
        ankle.push_back(std::abs(m.ankle_bend[s][f]));
        shin.push_back(m.angle[2 + s][f]);
        lift += m.lift[f];
        lift_worst = std::max(lift_worst, m.lift[f]);
      }
    ASSERT_GT(ankle.size(), 200u) << file << ": the crouch should be found";
    double ankle_sum = 0, shin_sum = 0;
    for (float x : ankle) ankle_sum += x;
    for (float x : shin) shin_sum += x;
    const double n = static_cast<double>(ankle.size());
    std::printf(
        "%s crouching (%zu foot-frames): ankle bend off by mean %.1f worst %.1f deg, %.1f %% "
        "within 5; shin "
        "mean %.1f worst %.1f deg; hips lifted mean %.3f worst %.3f m\n",
        file, ankle.size(), ankle_sum / n, *std::max_element(ankle.begin(), ankle.end()),
        100 * share_within(ankle, 5), shin_sum / n, *std::max_element(shin.begin(), shin.end()),
        lift / n, lift_worst);
    EXPECT_LT(ankle_sum / n, 3.0) << file << ": crouching, our ankles bend less than the source's";
    EXPECT_GE(share_within(ankle, 5), 0.9f) << file;
    EXPECT_LT(shin_sum / n, 1.0) << file;
    EXPECT_LT(lift / n, 0.004) << file << ": crouching, our body is lifted off the source's height";
  }
}
