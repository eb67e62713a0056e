// The skin as an implicit surface (paper section 3.1): the iso-surface F(x) = kIso of the sum of
// the primitives' fields, for one posture (primitives follow their joints).
//
// Each primitive contributes s * ((1 - q^2/k^2) / (1 - 1/k^2))^3 for q < k and 0 beyond, where q is
// the ellipsoidal distance (q = 1 on the primitive's ellipsoid) and k its reach (kEllipsoidReach,
// kMetaballReach). So a lone primitive's skin is exactly its ellipsoid, and metaballs blend.
// Inside the skin F > kIso; outside F < kIso. Distances and positions in metres.
#pragma once

#include <optional>
#include <span>
#include <vector>

#include <glm/glm.hpp>

#include "bb/modeler/body.h"

namespace bb::modeler {

inline constexpr float kIso = 1.0f;
inline constexpr float kEllipsoidReach = 1.25f;
inline constexpr float kMetaballReach = 2.0f;

struct Aabb {
  glm::vec3 min{1e30f}, max{-1e30f};
  void extend(const glm::vec3& p) { min = glm::min(min, p); max = glm::max(max, p); }
  glm::vec3 center() const { return 0.5f * (min + max); }
  glm::vec3 size() const { return max - min; }
};

// A primitive placed in the world for one posture.
struct PlacedPrimitive {
  glm::mat3 to_unit;     // world offset -> ellipsoid unit space (q = |to_unit * (x - center)|)
  glm::vec3 center;      // world, metres
  float reach2;          // k^2
  float inv_reach2;      // 1 / k^2
  float scale;           // strength / (1 - 1/k^2)^3
  float min_radius;      // smallest semi-axis, metres
  int joint;             // owning joint
  int source;            // index into Body::primitives
  Aabb support;          // world box of the region where the primitive's field is non-zero
};

// The outermost crossing of the iso-surface (kIso) of `prims`' summed field along the ray
// origin + t * d, 0 <= t <= max_t (t in units of |d|): per primitive, the span of t where it
// contributes; a march inwards from the far end of the spans in steps of a quarter of the
// thinnest contributing primitive's radius (at most 1 cm), then bisection to 1e-6. A ray whose
// far end lies inside the skin gives that end when `far_end_inside_counts`, else the march goes
// on to the first inside point after an outside one. Nothing when no crossing is found. The one
// implementation behind ImplicitSurface::outermost_intersection and the mesher's part fields.
std::optional<float> outermost_crossing(std::span<const PlacedPrimitive> prims, const glm::vec3& origin,
                                        const glm::vec3& d, float max_t, bool far_end_inside_counts);

class ImplicitSurface {
 public:
  // Places the body's primitives in `posture` (skeleton order, see Skeleton) and builds a
  // uniform grid over their supports so that a query touches only nearby primitives.
  ImplicitSurface(const Body& body, const Posture& posture);

  float field(const glm::vec3& x) const;
  // Field and its gradient (d F / d x, units 1/m) at x.
  float field_gradient(const glm::vec3& x, glm::vec3* gradient) const;
  // Field from the primitives of the given joints only (for per-part work); `joint_mask`
  // has one flag per skeleton joint.
  float field_of(const glm::vec3& x, const std::vector<char>& joint_mask) const;

  // The outermost crossing of the skin along the ray origin + t * unit(direction),
  // 0 <= t <= max_distance: the largest t where the field goes from inside to outside.
  // Returns t in metres, or nothing when the ray stays outside. Found to 1e-6 m; features
  // thinner than a quarter of the thinnest primitive's radius may be stepped over.
  std::optional<float> outermost_intersection(const glm::vec3& origin, const glm::vec3& direction,
                                              float max_distance) const;

  // Box of all supports (the field is 0 outside it).
  const Aabb& bounds() const { return bounds_; }
  const std::vector<PlacedPrimitive>& primitives() const { return prims_; }
  const std::vector<glm::mat4>& joint_transforms() const { return joints_; }

 private:
  std::vector<PlacedPrimitive> prims_;
  std::vector<glm::mat4> joints_;
  Aabb bounds_;
  // Uniform grid: cell -> range in cell_items_.
  glm::ivec3 dims_{1};
  glm::vec3 cell_size_{1};
  std::vector<int> cell_start_;  // size cells + 1
  std::vector<int> cell_items_;
  int cell_of(const glm::vec3& x) const;  // -1 when outside the grid
};

}  // namespace bb::modeler
