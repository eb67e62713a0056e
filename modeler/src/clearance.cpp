#include "bb/modeler/clearance.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "bb/modeler/implicit_surface.h"

namespace bb::modeler {
namespace {

constexpr float kStep = 0.0005f;   // march step, metres
constexpr float kReach = 0.35f;    // how far from the arm's axis the march looks for the torso, metres

}  // namespace

float arm_torso_gap_m(const Body& body, float abduction_rad) {
  constexpr float kNone = std::numeric_limits<float>::infinity();
  if (!body.skeleton) return kNone;
  const Skeleton& sk = *body.skeleton;
  const size_t nj = sk.joints().size();
  std::vector<char> torso(nj, 0);
  for (const char* n : {"sacroiliac", "vl5", "vt10", "vc7", "l_sternoclavicular", "r_sternoclavicular"}) {
    const int j = sk.find_joint(n);
    if (j < 0) return kNone;
    torso[j] = 1;
  }
  Posture p = sk.neutral();
  for (const char* s : {"l_", "r_"}) {
    const int d = sk.find_dof(std::string(s) + "shoulder.abduction");
    if (d < 0) return kNone;
    p[d] = abduction_rad;
  }
  sk.clamp(p);
  const ImplicitSurface skin(body, p);
  const std::vector<glm::mat4> world = sk.world_transforms(p);
  const float middle = world[0][3].x;
  float gap = kNone;
  for (const char* s : {"l_", "r_"}) {
    const int shoulder = sk.find_joint(std::string(s) + "shoulder"), elbow = sk.find_joint(std::string(s) + "elbow");
    if (shoulder < 0 || elbow < 0) return kNone;
    std::vector<char> arm(nj, 0);
    arm[shoulder] = arm[elbow] = 1;
    const glm::vec3 a(world[shoulder][3]), b(world[elbow][3]);
    const glm::vec3 axis = glm::normalize(b - a);
    for (float f : {0.45f, 0.6f, 0.75f}) {
      const glm::vec3 c = a + f * (b - a);
      glm::vec3 in(c.x > middle ? -1.0f : 1.0f, 0.0f, 0.0f);
      in -= glm::dot(in, axis) * axis;
      if (glm::length(in) < 1e-3f) continue;
      in = glm::normalize(in);
      if (skin.field_of(c, arm) < kIso) continue;  // no arm skin around the axis here
      float arm_end = -1, torso_start = -1;
      for (float t = 0; t <= kReach && arm_end < 0; t += kStep)
        if (skin.field_of(c + t * in, arm) < kIso) arm_end = t;
      for (float t = 0; t <= kReach && torso_start < 0; t += kStep)
        if (skin.field_of(c + t * in, torso) >= kIso) torso_start = t;
      if (arm_end < 0 || torso_start < 0) continue;  // no torso within reach, or an arm that big
      gap = std::min(gap, torso_start - arm_end);
    }
  }
  return gap;
}

float arm_abduction_for_clearance(const Body& body, float clearance_m, float min_rad, float max_rad) {
  if (arm_torso_gap_m(body, min_rad) >= clearance_m) return min_rad;
  if (arm_torso_gap_m(body, max_rad) < clearance_m) return max_rad;
  float lo = min_rad, hi = max_rad;  // gap(lo) < clearance <= gap(hi)
  const float tenth_degree = 0.1f * 3.14159265f / 180.0f;
  while (hi - lo > tenth_degree) {
    const float mid = 0.5f * (lo + hi);
    (arm_torso_gap_m(body, mid) >= clearance_m ? hi : lo) = mid;
  }
  return hi;
}

float walk_arm_abduction(const Body& body, float clearance_m) {
  return arm_abduction_for_clearance(body, clearance_m * body.height() / 1.75f, kWalkArmAbductionRad,
                                     kWalkArmAbductionMaxRad);
}

}  // namespace bb::modeler
