#include "bb/motion/walk.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include <glm/gtc/constants.hpp>

namespace bb::motion {

namespace {

constexpr float kPi = glm::pi<float>();
float deg(float d) { return glm::radians(d); }

// A periodic bump on the phase circle centred at c with width w (both in cycles).
float bump(float phase, float c, float w) {
  float d = phase - c;
  d -= std::round(d);
  return std::exp(-0.5f * (d / w) * (d / w));
}

struct Dofs {
  int tx, ty, tz, yaw, roll;
  int hip[2], hip_abd[2], knee[2], ankle[2], toe[2], shoulder[2], shoulder_abd[2], elbow[2];
  int spine_rot, spine_flex;
  int ankle_joint[2], toe_joint[2];
  bool ok = true;
};

Dofs find(const modeler::Skeleton& sk) {
  Dofs d;
  auto f = [&](const char* n) {
    int i = sk.find_dof(n);
    if (i < 0) d.ok = false;
    return i;
  };
  d.tx = f("HumanoidRoot.tx");
  d.ty = f("HumanoidRoot.ty");
  d.tz = f("HumanoidRoot.tz");
  d.yaw = f("HumanoidRoot.yaw");
  d.roll = f("HumanoidRoot.roll");
  const char* side[2] = {"l_", "r_"};
  for (int s = 0; s < 2; ++s) {
    std::string p = side[s];
    d.hip[s] = f((p + "hip.flexion").c_str());
    d.hip_abd[s] = f((p + "hip.abduction").c_str());
    d.knee[s] = f((p + "knee.flexion").c_str());
    d.ankle[s] = f((p + "ankle.dorsiflexion").c_str());
    d.toe[s] = f((p + "metatarsophalangeal.extension").c_str());
    d.shoulder[s] = f((p + "shoulder.flexion").c_str());
    d.shoulder_abd[s] = f((p + "shoulder.abduction").c_str());
    d.elbow[s] = f((p + "elbow.flexion").c_str());
    d.ankle_joint[s] = sk.find_joint(p + "ankle");
    d.toe_joint[s] = sk.find_joint(p + "metatarsophalangeal");
    if (d.ankle_joint[s] < 0 || d.toe_joint[s] < 0) d.ok = false;
  }
  d.spine_rot = f("vt10.rotation");
  d.spine_flex = f("vl5.flexion");
  return d;
}

// Leg angles of one side at its own phase (0 = heel strike), for a hip amplitude and step scale.
void leg(const Dofs& d, int s, float phase, float hip_amp, float scale, modeler::Posture& p) {
  float c = std::cos(2 * kPi * phase);
  // Hip flexes ~+25 deg at heel strike, extends at toe-off (phase ~0.6).
  p[d.hip[s]] = deg(5.0f) + hip_amp * c;
  // Knee: a small flexion at loading (0.12) and a large one in swing (0.72).
  p[d.knee[s]] = deg(4.0f) + deg(14.0f) * scale * bump(phase, 0.12f, 0.07f) +
                 deg(58.0f) * std::min(1.3f, 0.7f + 0.3f * scale) * bump(phase, 0.72f, 0.11f);
  // Ankle: plantarflexion after heel strike, dorsiflexion in mid stance, push-off, neutral swing.
  p[d.ankle[s]] = -deg(6.0f) * bump(phase, 0.05f, 0.04f) + deg(9.0f) * bump(phase, 0.40f, 0.1f) -
                  deg(18.0f) * scale * bump(phase, 0.62f, 0.05f) + deg(4.0f) * bump(phase, 0.85f, 0.08f);
  // Toes extend during push-off.
  p[d.toe[s]] = deg(25.0f) * bump(phase, 0.56f, 0.05f);
  p[d.hip_abd[s]] = deg(2.0f);
}

// Forward position (z, relative to the root's translation) of a side's ankle, and the lowest
// height of its ankle and toe joints, for a posture.
struct FootState { float x, z, y; };

FootState foot(const modeler::Skeleton& sk, const Dofs& d, int s, const modeler::Posture& p,
               std::vector<glm::mat4>& w) {
  sk.world_transforms(p, w);
  glm::vec3 a(w[d.ankle_joint[s]][3]), t(w[d.toe_joint[s]][3]);
  return {a.x - p[d.tx], a.z - p[d.tz], std::min(a.y, t.y) - p[d.ty]};
}

}  // namespace

WalkCycle walk_cycle(const modeler::Skeleton& sk, float v) {
  WalkCycle c;
  auto w = sk.world_transforms(sk.neutral());
  int hip = sk.find_joint("l_hip"), ankle = sk.find_joint("l_ankle");
  c.leg_length_m = hip >= 0 ? w[hip][3].y : 0.9f;
  if (ankle >= 0) c.leg_length_m = w[hip][3].y;  // hip height above the ground plane y = 0
  c.relative_velocity = v / c.leg_length_m;
  float rl = 1.346f * std::sqrt(c.relative_velocity);  // Boulic et al.: relative cycle length
  c.cycle_length_m = rl * c.leg_length_m;
  c.cycle_duration_s = c.cycle_length_m / v;
  return c;
}

Result<Clip> make_walk(const modeler::Skeleton& sk, const WalkParams& wp) {
  if (!(wp.speed_mps >= 0.3f && wp.speed_mps <= 2.5f))
    return Error{"", "speed", "walking speed must be within 0.3 .. 2.5 m/s"};
  if (!(wp.fps >= 5 && wp.fps <= 240)) return Error{"", "fps", "frame rate must be within 5 .. 240"};
  if (!(wp.arm_abduction_rad >= 0 && wp.arm_abduction_rad <= deg(45.0f)))
    return Error{"", "arm_abduction_rad", "the arms' abduction must be within 0 .. 45 degrees"};
  Dofs d = find(sk);
  if (!d.ok) return Error{"", "skeleton", "the walk needs the H-Anim joints and DOFs of data/skeleton.json"};
  WalkCycle cyc = walk_cycle(sk, wp.speed_mps);
  float scale = std::sqrt(cyc.relative_velocity);  // 1 at RV = 1
  std::vector<glm::mat4> w(sk.joints().size());
  modeler::Posture rest = sk.neutral();
  const float ground = std::min(foot(sk, d, 0, rest, w).y, foot(sk, d, 1, rest, w).y);

  // Solve the hip amplitude so that, over half a cycle, the driving (left) foot moves back by
  // half a cycle length relative to the root: then it is planted when the body moves at v.
  auto sweep = [&](float amp) {
    modeler::Posture p = rest;
    leg(d, 0, 0.0f, amp, scale, p);
    float z0 = foot(sk, d, 0, p, w).z;
    leg(d, 0, 0.5f, amp, scale, p);
    return z0 - foot(sk, d, 0, p, w).z;
  };
  float lo = deg(2), hi = deg(50), half = 0.5f * cyc.cycle_length_m;
  for (int it = 0; it < 40; ++it) {
    float mid = 0.5f * (lo + hi);
    (sweep(mid) < half ? lo : hi) = mid;
  }
  cyc.hip_amplitude_rad = 0.5f * (lo + hi);

  int n = std::max(8, static_cast<int>(std::lround(cyc.cycle_duration_s * wp.fps)));
  float fps = n / cyc.cycle_duration_s;  // exact loop: n frames span one cycle
  Clip clip;
  char name[64];
  std::snprintf(name, sizeof name, "walk_%.2fmps", wp.speed_mps);
  clip.name = name;
  clip.fps = fps;
  clip.loops = !wp.travelling;
  clip.speed_mps = wp.speed_mps;
  // Root forward offset: the driving foot's own backward sweep cancels the body's motion.
  // Left drives during [0, 0.5), right during [0.5, 1).
  // Everything but the root's forward and vertical translation, at a phase.
  auto pose = [&](float phase) {
    modeler::Posture p = rest;
    for (int s = 0; s < 2; ++s) leg(d, s, std::fmod(phase + 0.5f * s, 1.0f), cyc.hip_amplitude_rad, scale, p);
    float c = std::cos(2 * kPi * phase);
    // Pelvis: rotation towards the swinging leg, list, lateral shift; spine counter-rotation.
    p[d.yaw] = deg(4.0f) * scale * c;
    p[d.roll] = deg(2.5f) * std::sin(4 * kPi * phase);
    p[d.spine_rot] = -deg(6.0f) * scale * c;
    p[d.spine_flex] = deg(3.0f) * scale;
    // Arms swing against the legs; elbows bend more on the forward swing.
    for (int s = 0; s < 2; ++s) {
      float cs = s == 0 ? c : -c;
      p[d.shoulder[s]] = -deg(16.0f) * scale * cs;
      p[d.shoulder_abd[s]] = wp.arm_abduction_rad;
      p[d.elbow[s]] = deg(18.0f) + deg(12.0f) * scale * (1.0f - cs) * 0.5f;
    }
    sk.clamp(p);
    return p;
  };
  // Root forward offset: left drives during [0, 0.5), right during [0.5, 1). The driving foot's
  // backward sweep relative to the root cancels the body's forward motion, so the offset goes
  // from 0 back to 0 over each half cycle (the hip amplitude was solved for that).
  const FootState start[2] = {foot(sk, d, 0, pose(0.0f), w), foot(sk, d, 1, pose(0.5f), w)};
  for (int f = 0; f <= n; ++f) {
    float phase = static_cast<float>(f % n) / n;
    modeler::Posture p = pose(phase);
    int drive = phase < 0.5f ? 0 : 1;
    float t = (drive == 0 ? phase : phase - 0.5f) * cyc.cycle_duration_s;
    FootState fs = foot(sk, d, drive, p, w);
    p[d.tz] = (start[drive].z - fs.z) - wp.speed_mps * t;
    // Sideways, the pelvis sways over the driving foot, which keeps its place.
    p[d.tx] = start[drive].x - fs.x;
    if (wp.travelling) p[d.tz] += wp.speed_mps * (static_cast<float>(f) / fps);
    // Vertical: the lower foot touches the ground.
    float low = std::min(foot(sk, d, 0, p, w).y, foot(sk, d, 1, p, w).y);
    p[d.ty] = ground - low;
    sk.clamp(p);
    clip.frames.push_back(std::move(p));
  }
  return clip;
}

}  // namespace bb::motion
