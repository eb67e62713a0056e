// Motion capture: BVH import, retargeted onto the bodybuilder skeleton.
//
// Parsing accepts LF and CRLF files, a UTF-8 byte order mark, tabs, any rotation order per joint and
// any subset of the six channels. Each frame is one line of exactly as many values as the hierarchy
// declares channels, and there are exactly as many frames as "Frames:" says (blank lines aside);
// errors name the file, the line and the reason. Retargeting finds the BVH bones by role
// (hips, spine, neck, head, collar, upper arm, forearm, wrist, thigh, shin, foot, toe) under the
// names the common conventions give them, compared without case, '_', '-', '.' and namespace
// prefixes: CMU's two conversions (LeftUpLeg/LeftLeg/LeftFoot/LowerBack/Spine/LeftShoulder/LeftArm
// ... and LeftHip/LeftKnee/LeftAnkle/lowerback/Chest/LeftCollar/LeftShoulder/LeftElbow ...), the
// Daz-friendly release (hip/abdomen/chest/lThigh/lShin/lFoot/lCollar/lShldr/lForeArm/lHand), the
// original ASF names (lfemur/ltibia/lfoot/lclavicle/lhumerus/lradius/lwrist), Mixamo
// (mixamorig:LeftUpLeg ...) and thigh_l/calf_l/foot_l; a file without thighs, shins and feet on both
// sides is refused. It takes the root's full rotation (any facing) and places our hip joints where
// the BVH's are (scaled by the ratio of leg lengths, over a ground at the clip's median lower-ankle
// height) and, for every other mapped joint (toes included), turns our link to point the way the BVH
// bone points (a least-squares fit of the joint's own DOFs, clamped to their limits; the twist about a
// bone is not transferred; a foot's angle to its shin moves from our rest angle as the source's
// moves from its rest pose's: CMU's flat foot bone rests 101-104 degrees from the shin, ours 109).
// No foot point goes below the floor (y = 0): a toe tip there extends its toe, then the body rises
// as far as needed. The clip keeps the BVH's frame count and frame rate.
#pragma once

#include <string>
#include <string_view>
#include <vector>

#include <glm/glm.hpp>

#include "bb/modeler/skeleton.h"
#include "bb/motion/clip.h"
#include "bb/result.h"

namespace bb::motion {

struct BvhJoint {
  std::string name;
  int parent = -1;
  glm::vec3 offset{0};
  std::vector<int> channels;  // 0..2 X/Y/Zposition, 3..5 X/Y/Zrotation, in file order
  int first_channel = 0;      // index of its first value in a frame
  bool end_site = false;
};

struct BvhFile {
  std::vector<BvhJoint> joints;  // parents before children
  int channel_count = 0;
  float frame_time = 0;          // seconds
  std::vector<std::vector<float>> frames;
};

// Parses BVH text; `file` names it in errors ("file: line N: reason").
Result<BvhFile> parse_bvh(std::string_view text, std::string_view file);

// World positions of every BVH joint in frame `frame` (the rest pose when out of range).
std::vector<glm::vec3> world_positions(const BvhFile& bvh, size_t frame);

// Reads, parses and retargets a BVH file onto `target` (needs the H-Anim joints of
// data/skeleton.json). The clip is named after the file's stem.
Result<Clip> load_bvh(const std::string& path, const modeler::Skeleton& target);

// Retargets parsed motion; `name` becomes the clip's name.
Result<Clip> retarget(const BvhFile& bvh, const modeler::Skeleton& target, const std::string& name,
                      std::string_view file = {});

}  // namespace bb::motion
