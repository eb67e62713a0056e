// A procedural walk for the bodybuilder skeleton, after Boulic, Magnenat-Thalmann and Thalmann,
// "A global human walking model with real-time kinematic personification" (The Visual Computer,
// 1990): the walk is normalized by the leg length (relative velocity RV = v / H_t, H_t the hip
// height) and the relative cycle length follows RL_c = 1.346 sqrt(RV); the cycle duration is
// then D_c = RL_c H_t / v. Joint trajectories are smooth periodic functions of the cycle phase
// scaled by the step length.
//
// The clip is one seamless, in-place cycle (loops = true, the last frame equals the first): the
// root's forward translation (HumanoidRoot.tz) oscillates with no net travel so that a character
// moved forward at speed_mps keeps its driving foot exactly planted (its world velocity is 0
// while it carries the body). `travelling` adds the forward motion to the root instead.
// Units: metres, seconds, radians in the postures.
#pragma once

#include <vector>

#include "bb/modeler/clearance.h"
#include "bb/modeler/skeleton.h"
#include "bb/motion/clip.h"
#include "bb/result.h"

namespace bb::motion {

struct WalkParams {
  float speed_mps = 1.2f;   // 0.3 .. 2.5
  float fps = 30.0f;        // frames per second of the baked clip
  bool travelling = false;  // root moves forward at speed_mps (the clip then does not loop)
  // How far out of the neutral posture both arms hang, radians, 0 .. pi/4 (default 9 degrees). A
  // heavy body wants more, or its upper arms sink into its torso: modeler::walk_arm_abduction
  // (bb/modeler/clearance.h) finds the angle for a body, and exporter::build_body passes it here.
  float arm_abduction_rad = modeler::kWalkArmAbductionRad;
};

struct WalkCycle {
  float leg_length_m = 0;      // H_t: hip height in the neutral posture
  float relative_velocity = 0; // RV = v / H_t
  float cycle_length_m = 0;    // two steps
  float cycle_duration_s = 0;
  float hip_amplitude_rad = 0; // solved so the driving foot covers one step per half cycle
};

// The cycle the walk model gives for `speed` on this skeleton (no clip).
WalkCycle walk_cycle(const modeler::Skeleton& skeleton, float speed_mps);

// One cycle of walking, named "walk_<speed>mps" (e.g. "walk_1.20mps"). Every frame is within the
// skeleton's joint limits. Needs the H-Anim joints of data/skeleton.json.
Result<Clip> make_walk(const modeler::Skeleton& skeleton, const WalkParams& params = {});

}  // namespace bb::motion
