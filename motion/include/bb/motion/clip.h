// A motion clip over the bodybuilder skeleton: one posture (74 DOF values, see
// bb/modeler/skeleton.h) per frame at a fixed frame rate. The exporter turns a clip into glTF
// animation channels through Skeleton::local_transform.
#pragma once

#include <string>
#include <vector>

#include "bb/modeler/skeleton.h"

namespace bb::motion {

struct Clip {
  std::string name;                       // glTF animation name, e.g. "walk_1.20mps"
  float fps = 30.0f;                      // frames per second, > 0
  std::vector<modeler::Posture> frames;   // >= 1 frames, each Skeleton::dof_count() values
  bool loops = false;                     // the last frame equals the first (a seamless cycle)
  float speed_mps = 0.0f;                 // forward speed of the root for walks (0: unknown)
  // Seconds from the first to the last frame.
  float duration() const { return frames.size() > 1 ? (frames.size() - 1) / fps : 0.0f; }
};

}  // namespace bb::motion
