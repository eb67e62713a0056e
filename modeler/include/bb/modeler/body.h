// Section 3.1 of the paper: the layered body. Bone ellipsoids and muscle/fat ellipsoidal
// metaballs, each attached to its proximal joint; together they define an implicit surface,
// the skin (see implicit_surface.h).
//
// Units: metres. A primitive's centre, radii and orientation are given in its joint's frame.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include <glm/glm.hpp>
#include <glm/gtc/quaternion.hpp>

#include "bb/modeler/skeleton.h"
#include "bb/result.h"

namespace bb::modeler {

enum class PrimitiveType {
  kEllipsoid,  // bone layer: a sharp field that keeps its own shape
  kMetaball,   // muscle and fat layer: a soft field that blends with its neighbours
};

// A human's primitive lies near its joint: body files with a semi-axis or a centre offset beyond
// this (metres) are rejected (a 50 m "pelvis" would mesh without complaint into nonsense).
inline constexpr float kMaxPrimitiveExtent = 2.0f;

struct Primitive {
  std::string name;               // optional label, e.g. "l_thigh_front"
  PrimitiveType type = PrimitiveType::kMetaball;
  int joint = 0;                  // index into the skeleton's joints
  glm::vec3 center{0};            // joint frame, metres, |each| <= kMaxPrimitiveExtent
  glm::vec3 radii{0.05f};         // semi-axes, metres, in (0, kMaxPrimitiveExtent]
  glm::quat orientation{1, 0, 0, 0};  // joint frame
  float strength = 1.0f;          // field multiplier, > 0 (1: the lone primitive's skin is its ellipsoid)
};

// Parameters that make different-looking bodies from one description.
struct BodyShape {
  float height_m = 0;    // target standing height; 0 keeps the description's height
  float build = 1.0f;    // girth of the muscle/fat layer: 0.8 slim .. 1.3 heavy
  uint64_t seed = 0;     // 0: no random variation; otherwise per-region random girth and proportions
};

struct Body {
  std::string name;
  std::shared_ptr<const Skeleton> skeleton;
  std::vector<Primitive> primitives;
  std::string sample_posture = "bind";  // posture the mesher samples the skin in (the bind pose)

  // Standing height in the neutral posture: top of the skin minus the bottom, metres.
  float height() const;
  int count(PrimitiveType t) const;
};

// Parses a body JSON text. `file` names it in errors; relative "skeleton" paths are resolved
// against `base_dir`. Without a "skeleton" key the built-in skeleton is used.
Result<Body> parse_body(std::string_view json_text, std::string_view file,
                        const std::string& base_dir = ".");
Result<Body> load_body(const std::string& path);
// The body built into the program (data/bodies/default.json at build time).
const Body& default_body();

// A body's name is the stem of the files built from it (DIR/<name>.glb): at most this many bytes.
inline constexpr size_t kMaxBodyNameBytes = 200;

// Empty when `name` may name a body: 1 to kMaxBodyNameBytes bytes of valid UTF-8 with no '/', '\\',
// NUL or other control character (C0, DEL, C1), and not "." or "..". Otherwise what is wrong and
// what a name may hold. parse_body refuses other names at $.name.
std::string body_name_problem(std::string_view name);

// A body of another height, build and, with a seed, randomly varied proportions. The result
// is deterministic for a given (body, shape). Its name is "<name>" + suffix when suffix is given.
Body make_variant(const Body& body, const BodyShape& shape, std::string_view name_suffix = {});

}  // namespace bb::modeler
