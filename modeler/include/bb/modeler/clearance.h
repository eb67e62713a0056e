// How far the hanging arms stay from the torso: the air between each upper arm's skin and the
// torso's, for the walk's arm posture (the procedural walk holds its arms a fixed angle out of the
// neutral posture). A heavy body whose arms hang as close as a slim one's pushes them into its
// chest and back, and linear blend skinning then folds the armpits over (seeded variant 1, 19 %
// broader, sank its upper arms 21 mm into the torso at the walk's 9 degrees and turned 20-49 cm2
// of skin over at levels 1 and 2). Units: metres, radians.
#pragma once

#include "bb/modeler/body.h"

namespace bb::modeler {

// The narrowest air (metres; negative: how deep the skins overlap) between either upper arm and the
// torso with both shoulders abducted `abduction_rad` out of the neutral posture, everything else
// neutral. Measured at 45, 60 and 75 % of the way from the shoulder to the elbow (nearer the
// shoulder the arm's and the torso's skins blend by design): from the upper arm's axis, level and
// square to the arm, towards the body's middle, the distance from where the arm's own field (the
// shoulder's and the elbow's primitives) drops below the iso-value to where the torso's (pelvis,
// spine and collarbones) reaches it. A side whose arm or torso has no primitives there does not
// count; with neither side counting, +infinity. The body needs the H-Anim joints of
// data/skeleton.json (sacroiliac, vl5, vt10, vc7, l_/r_ sternoclavicular, shoulder, elbow); without
// them, +infinity.
float arm_torso_gap_m(const Body& body, float abduction_rad);

// The smallest shoulder abduction in [min_rad, max_rad] at which arm_torso_gap_m is at least
// `clearance_m`, to 0.1 degree (the gap grows as the arms rise); min_rad when it already is, max_rad
// when even that is not enough.
float arm_abduction_for_clearance(const Body& body, float clearance_m, float min_rad, float max_rad);

// The procedural walk's arms (motion::WalkParams::arm_abduction_rad): 9 degrees out of the neutral
// posture, or as far as this body needs for `clearance_m` of air (metres for a body 1.75 m tall,
// scaled by its height), at most 30 degrees. Measured with 1 cm: the default body 9 degrees (17 mm
// of air there), seeded variants 1-3 19.1 / 14.0 / 14.3 degrees (at 9, -21 / -5 / -5 mm).
inline constexpr float kWalkArmAbductionRad = 0.15707963f;     // 9 degrees
inline constexpr float kWalkArmAbductionMaxRad = 0.52359878f;  // 30 degrees
inline constexpr float kWalkArmClearanceM = 0.01f;
float walk_arm_abduction(const Body& body, float clearance_m = kWalkArmClearanceM);

}  // namespace bb::modeler
