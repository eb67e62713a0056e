// Section 3.2 of the paper: a hierarchy of the main human joints with 74 degrees of freedom,
// each limited to the range a real human reaches.
//
// Units: metres and radians in memory (the data file gives limits in degrees). Axes: Y up, the
// body faces +Z, its left is +X (glTF's convention). In the neutral posture (every DOF 0) each
// joint frame is parallel to the world frame; a joint's local transform is
//   T(offset) * T(translation DOFs) * R(dof0) * R(dof1) * ...   (DOFs in file order).
#pragma once

#include <array>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include <glm/glm.hpp>

#include "bb/result.h"

namespace bb::modeler {

enum class DofType { kRotation, kTranslation };

struct Dof {
  std::string name;      // e.g. "flexion"; its full name is "<joint>.<name>"
  DofType type = DofType::kRotation;
  glm::vec3 axis{1, 0, 0};  // unit vector in the joint frame
  float min = 0, max = 0;   // radians (rotation) or metres (translation), min <= max
};

struct Joint {
  std::string name;        // H-Anim name, unique
  int parent = -1;         // index into Skeleton::joints, always < this joint's index; -1 for the root
  glm::vec3 offset{0};     // position in the parent frame in the neutral posture, metres
  int first_dof = 0;       // index of this joint's first DOF in a posture vector
  std::vector<Dof> dofs;   // 0..6 DOFs
};

// A posture: one value per DOF, in Skeleton order (radians or metres).
using Posture = std::vector<float>;

class Skeleton {
 public:
  // Joints in topological order: parents before children; joint 0 is the root.
  const std::vector<Joint>& joints() const { return joints_; }
  int dof_count() const { return dof_count_; }
  // Index of the joint named `name`, or -1.
  int find_joint(std::string_view name) const;
  // Index in a posture of the DOF named "joint.dof", or -1.
  int find_dof(std::string_view full_name) const;
  const Dof& dof(int index) const;  // 0 <= index < dof_count()
  int dof_joint(int index) const { return dof_joint_[index]; }

  // All-zero posture.
  Posture neutral() const { return Posture(dof_count_, 0.0f); }
  // A named posture from the data file ("neutral", "bind", "max_extent"); neutral if unknown.
  Posture posture(std::string_view name) const;
  const std::vector<std::string>& posture_names() const { return posture_names_; }

  // Clamps every DOF of `p` to its limits; returns how many values changed.
  int clamp(Posture& p) const;
  // Whether every DOF of `p` is within its limits (inclusive, with `eps` slack).
  bool within_limits(const Posture& p, float eps = 1e-6f) const;

  // Forward kinematics: world transform of every joint (size = joints().size()).
  // `p` must have dof_count() values. Allocation-free overload writes into `out`.
  std::vector<glm::mat4> world_transforms(const Posture& p) const;
  void world_transforms(const Posture& p, std::span<glm::mat4> out) const;
  // Local transform of joint `j` (relative to its parent) for posture `p`.
  glm::mat4 local_transform(int j, const Posture& p) const;

  // Section 4.2: the fixed point Ta, the spine base (joint "vl5", else the root) in the
  // maximal-extent posture, in metres, with the root at its neutral place.
  glm::vec3 ta() const;

  // Moves joint `j` to `offset` in its parent frame (variants scale their skeleton this way).
  void set_offset(int j, const glm::vec3& offset) { joints_[j].offset = offset; }

  std::string name;
  std::string limits_source;

 private:
  friend Result<Skeleton> parse_skeleton(std::string_view, std::string_view);
  std::vector<Joint> joints_;
  std::vector<int> dof_joint_;
  int dof_count_ = 0;
  std::vector<std::string> posture_names_;
  std::vector<std::vector<std::pair<int, float>>> postures_;  // sparse (dof, value)
};

// Parses a skeleton JSON text; `file` names it in errors. Errors carry a JSON path.
Result<Skeleton> parse_skeleton(std::string_view json_text, std::string_view file);
// Reads and parses a skeleton file.
Result<Skeleton> load_skeleton(const std::string& path);
// The skeleton built into the program (data/skeleton.json at build time).
const Skeleton& default_skeleton();

}  // namespace bb::modeler
