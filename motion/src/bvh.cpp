#include "bb/motion/bvh.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>

#include <glm/gtc/matrix_transform.hpp>

namespace bb::motion {

namespace {

struct Lexer {
  std::string_view text;
  size_t pos = 0;
  int line = 1;
  std::string_view next() {
    while (pos < text.size() && std::isspace(static_cast<unsigned char>(text[pos]))) {
      if (text[pos] == '\n') ++line;
      ++pos;
    }
    size_t b = pos;
    while (pos < text.size() && !std::isspace(static_cast<unsigned char>(text[pos]))) ++pos;
    return text.substr(b, pos - b);
  }
};

struct ParseError {
  int line;
  std::string reason;
};

float to_float(std::string_view s, int line, const char* what) {
  float v = 0;
  std::string t(s);
  char* end = nullptr;
  v = std::strtof(t.c_str(), &end);
  if (t.empty() || !end || *end != '\0' || !std::isfinite(v))
    throw ParseError{line, std::string("expected a number for ") + what + ", got \"" + t + "\""};
  return v;
}

int channel_of(std::string_view s) {
  static const char* names[] = {"Xposition", "Yposition", "Zposition", "Xrotation", "Yrotation", "Zrotation"};
  for (int i = 0; i < 6; ++i)
    if (s == names[i]) return i;
  return -1;
}

}  // namespace

Result<BvhFile> parse_bvh(std::string_view text, std::string_view file) {
  BvhFile out;
  Lexer lx{text};
  try {
    if (lx.next() != "HIERARCHY") throw ParseError{lx.line, "expected HIERARCHY at the start"};
    std::vector<int> stack;
    int channels = 0;
    std::string_view tok = lx.next();
    if (tok != "ROOT") throw ParseError{lx.line, "expected ROOT"};
    while (true) {
      // tok is ROOT, JOINT or End
      BvhJoint j;
      j.parent = stack.empty() ? -1 : stack.back();
      if (tok == "End") {
        if (lx.next() != "Site") throw ParseError{lx.line, "expected \"End Site\""};
        j.end_site = true;
        j.name = (j.parent >= 0 ? out.joints[j.parent].name : std::string("root")) + "_end";
      } else {
        j.name = std::string(lx.next());
        if (j.name.empty() || j.name == "{") throw ParseError{lx.line, "missing joint name"};
      }
      if (lx.next() != "{") throw ParseError{lx.line, "expected '{' after " + j.name};
      if (lx.next() != "OFFSET") throw ParseError{lx.line, "expected OFFSET in " + j.name};
      for (int k = 0; k < 3; ++k) j.offset[k] = to_float(lx.next(), lx.line, "OFFSET");
      tok = lx.next();
      if (!j.end_site) {
        if (tok != "CHANNELS") throw ParseError{lx.line, "expected CHANNELS in " + j.name};
        std::string_view n = lx.next();
        int count = static_cast<int>(to_float(n, lx.line, "the channel count"));
        if (count < 0 || count > 6) throw ParseError{lx.line, "channel count must be 0..6, got " + std::string(n)};
        j.first_channel = channels;
        for (int c = 0; c < count; ++c) {
          std::string_view cn = lx.next();
          int ch = channel_of(cn);
          if (ch < 0) throw ParseError{lx.line, "unknown channel \"" + std::string(cn) + "\" in " + j.name};
          j.channels.push_back(ch);
        }
        channels += count;
        tok = lx.next();
      }
      out.joints.push_back(j);
      stack.push_back(static_cast<int>(out.joints.size() - 1));
      // Children or closing braces.
      while (tok == "}") {
        stack.pop_back();
        tok = lx.next();
        if (stack.empty()) break;
      }
      if (stack.empty()) break;
      if (tok != "JOINT" && tok != "End")
        throw ParseError{lx.line, "expected JOINT, End Site or '}', got \"" + std::string(tok) + "\""};
    }
    out.channel_count = channels;
    if (tok != "MOTION") throw ParseError{lx.line, "expected MOTION after the hierarchy"};
    if (lx.next() != "Frames:") throw ParseError{lx.line, "expected \"Frames:\""};
    std::string_view nf = lx.next();
    float frames_f = to_float(nf, lx.line, "the frame count");
    if (frames_f < 1 || frames_f != std::floor(frames_f)) throw ParseError{lx.line, "frame count must be a positive integer"};
    int frames = static_cast<int>(frames_f);
    if (lx.next() != "Frame" || lx.next() != "Time:") throw ParseError{lx.line, "expected \"Frame Time:\""};
    out.frame_time = to_float(lx.next(), lx.line, "the frame time");
    if (!(out.frame_time > 0)) throw ParseError{lx.line, "frame time must be positive"};
    out.frames.resize(frames);
    for (int f = 0; f < frames; ++f) {
      out.frames[f].resize(channels);
      int line = 0;
      for (int c = 0; c < channels; ++c) {
        std::string_view v = lx.next();
        if (c == 0) line = lx.line;
        if (v.empty())
          throw ParseError{lx.line, "file ends in frame " + std::to_string(f + 1) + " of " + std::to_string(frames) +
                                        " (truncated?)"};
        out.frames[f][c] = to_float(v, lx.line, "a channel value");
      }
      // A frame is one line: more or fewer values there is a wrong channel count.
      size_t save = lx.pos;
      int save_line = lx.line;
      std::string_view extra = lx.next();
      if (!extra.empty() && lx.line == line && f + 1 <= frames)
        throw ParseError{line, "frame " + std::to_string(f + 1) + " has more than the " + std::to_string(channels) +
                                   " values the hierarchy declares"};
      lx.pos = save;
      lx.line = save_line;
    }
  } catch (const ParseError& e) {
    return Error{std::string(file), "line " + std::to_string(e.line), e.reason};
  }
  return out;
}

namespace {

// Our joint -> (BVH bone start, bone end) for the two CMU namings.
struct Link {
  const char* ours;
  const char* from01;
  const char* to01;
  const char* from131;
  const char* to131;
};
const Link kLinks[] = {
    {"vl5", "LowerBack", "Spine", "lowerback", "Chest"},
    {"vt10", "Spine", "Neck", "Chest", "lowerneck"},
    {"vc7", "Neck", "Neck1", "lowerneck", "Neck"},
    {"skullbase", "Neck1", "Head", "Neck", "Head"},
    {"l_sternoclavicular", "LeftShoulder", "LeftArm", "LeftCollar", "LeftShoulder"},
    {"l_shoulder", "LeftArm", "LeftForeArm", "LeftShoulder", "LeftElbow"},
    {"l_elbow", "LeftForeArm", "LeftHand", "LeftElbow", "LeftWrist"},
    {"l_wrist", "LeftHand", "LeftFingerBase", "LeftWrist", "lhand"},
    {"r_sternoclavicular", "RightShoulder", "RightArm", "RightCollar", "RightShoulder"},
    {"r_shoulder", "RightArm", "RightForeArm", "RightShoulder", "RightElbow"},
    {"r_elbow", "RightForeArm", "RightHand", "RightElbow", "RightWrist"},
    {"r_wrist", "RightHand", "RightFingerBase", "RightWrist", "rhand"},
    {"l_hip", "LeftUpLeg", "LeftLeg", "LeftHip", "LeftKnee"},
    {"l_knee", "LeftLeg", "LeftFoot", "LeftKnee", "LeftAnkle"},
    {"l_ankle", "LeftFoot", "LeftToeBase", "LeftAnkle", "LeftToe"},
    {"r_hip", "RightUpLeg", "RightLeg", "RightHip", "RightKnee"},
    {"r_knee", "RightLeg", "RightFoot", "RightKnee", "RightAnkle"},
    {"r_ankle", "RightFoot", "RightToeBase", "RightAnkle", "RightToe"},
};
// Our child joint whose direction from `ours` is the link.
const char* child_of(const std::string& ours) {
  static const std::map<std::string, const char*> m = {
      {"vl5", "vt10"}, {"vt10", "vc7"}, {"vc7", "skullbase"}, {"skullbase", "skull_tip"},
      {"l_sternoclavicular", "l_shoulder"}, {"l_shoulder", "l_elbow"}, {"l_elbow", "l_wrist"}, {"l_wrist", "l_middle1"},
      {"r_sternoclavicular", "r_shoulder"}, {"r_shoulder", "r_elbow"}, {"r_elbow", "r_wrist"}, {"r_wrist", "r_middle1"},
      {"l_hip", "l_knee"}, {"l_knee", "l_ankle"}, {"l_ankle", "l_metatarsophalangeal"},
      {"r_hip", "r_knee"}, {"r_knee", "r_ankle"}, {"r_ankle", "r_metatarsophalangeal"}};
  auto it = m.find(ours);
  return it == m.end() ? nullptr : it->second;
}

glm::mat3 dof_rotation(const modeler::Joint& j, const float* v) {
  glm::mat4 r(1.0f);
  for (size_t k = 0; k < j.dofs.size(); ++k)
    if (j.dofs[k].type == modeler::DofType::kRotation) r = r * glm::rotate(glm::mat4(1.0f), v[k], j.dofs[k].axis);
  return glm::mat3(r);
}

// Fits the rotation DOFs of joint j so that R(theta) * vec[i] points along target[i] (local
// frames), weighted, with a small pull towards 0 so that unused twist stays put. Projected
// Gauss-Newton with a numeric Jacobian.
void fit_vectors(const modeler::Joint& j, int count, const glm::vec3* vec, const glm::vec3* target,
                 const float* weight, float* v) {
  const int n = static_cast<int>(j.dofs.size());
  if (n == 0) return;
  const float lambda = 1e-3f, h = 1e-3f;
  auto residual = [&](float* r) {
    glm::mat3 R = dof_rotation(j, v);
    for (int i = 0; i < count; ++i) {
      glm::vec3 e = (R * vec[i] - target[i]) * weight[i];
      for (int c = 0; c < 3; ++c) r[3 * i + c] = e[c];
    }
  };
  float r0[6], rp[6], J[6][6];
  for (int it = 0; it < 12; ++it) {
    residual(r0);
    for (int k = 0; k < n; ++k) {
      float old = v[k];
      v[k] = old + h;
      residual(rp);
      v[k] = old;
      for (int c = 0; c < 3 * count; ++c) J[k][c] = (rp[c] - r0[c]) / h;
    }
    double A[6][6] = {}, b[6] = {};
    for (int p = 0; p < n; ++p) {
      for (int q = 0; q < n; ++q)
        for (int c = 0; c < 3 * count; ++c) A[p][q] += J[p][c] * J[q][c];
      A[p][p] += lambda;
      for (int c = 0; c < 3 * count; ++c) b[p] -= J[p][c] * r0[c];
      b[p] -= lambda * v[p];
    }
    for (int p = 0; p < n; ++p) {
      int piv = p;
      for (int q = p + 1; q < n; ++q) if (std::abs(A[q][p]) > std::abs(A[piv][p])) piv = q;
      std::swap(A[p], A[piv]);
      std::swap(b[p], b[piv]);
      if (std::abs(A[p][p]) < 1e-12) continue;
      for (int q = p + 1; q < n; ++q) {
        double f = A[q][p] / A[p][p];
        for (int c = p; c < n; ++c) A[q][c] -= f * A[p][c];
        b[q] -= f * b[p];
      }
    }
    double x[6] = {};
    for (int p = n - 1; p >= 0; --p) {
      double sum = b[p];
      for (int c = p + 1; c < n; ++c) sum -= A[p][c] * x[c];
      x[p] = std::abs(A[p][p]) < 1e-12 ? 0 : sum / A[p][p];
    }
    float step = 0;
    for (int k = 0; k < n; ++k) {
      float nv = std::clamp(v[k] + static_cast<float>(x[k]), j.dofs[k].min, j.dofs[k].max);
      step = std::max(step, std::abs(nv - v[k]));
      v[k] = nv;
    }
    if (step < 1e-5f) break;
  }
}

void fit_direction(const modeler::Joint& j, const glm::vec3& d0, const glm::vec3& target, float* v) {
  const float w = 1.0f;
  fit_vectors(j, 1, &d0, &target, &w, v);
}

glm::mat3 euler(int ch, float deg) {
  glm::vec3 axis(ch == 3, ch == 4, ch == 5);
  return glm::mat3(glm::rotate(glm::mat4(1.0f), glm::radians(deg), axis));
}

// BVH forward kinematics: world rotation and position of every joint; rest pose without a frame.
void bvh_forward(const BvhFile& bvh, const std::vector<float>* frame, std::vector<glm::mat3>& brot,
                 std::vector<glm::vec3>& bpos) {
  for (size_t i = 0; i < bvh.joints.size(); ++i) {
    const BvhJoint& j = bvh.joints[i];
    glm::vec3 t = j.offset;
    glm::mat3 r(1.0f);
    if (frame)
      for (size_t c = 0; c < j.channels.size(); ++c) {
        float v = (*frame)[j.first_channel + c];
        int ch = j.channels[c];
        if (ch < 3) t[ch] = v;  // positions replace the offset (root)
        else r = r * euler(ch, v);
      }
    if (j.parent < 0) {
      brot[i] = r;
      bpos[i] = t;
    } else {
      brot[i] = brot[j.parent] * r;
      bpos[i] = bpos[j.parent] + brot[j.parent] * t;
    }
  }
}

}  // namespace

std::vector<glm::vec3> world_positions(const BvhFile& bvh, size_t frame) {
  std::vector<glm::mat3> rot(bvh.joints.size());
  std::vector<glm::vec3> pos(bvh.joints.size());
  bvh_forward(bvh, frame < bvh.frames.size() ? &bvh.frames[frame] : nullptr, rot, pos);
  return pos;
}

Result<Clip> retarget(const BvhFile& bvh, const modeler::Skeleton& sk, const std::string& name, std::string_view file) {
  std::map<std::string, int> by_name;
  for (size_t i = 0; i < bvh.joints.size(); ++i) by_name[bvh.joints[i].name] = static_cast<int>(i);
  bool cmu01 = by_name.count("LeftUpLeg"), cmu131 = by_name.count("LeftHip");
  if (!cmu01 && !cmu131)
    return Error{std::string(file), "HIERARCHY",
                 "unknown joint naming: expected the CMU names (LeftUpLeg/LeftLeg/... or LeftHip/LeftKnee/...)"};
  int hips = by_name.count("Hips") ? by_name["Hips"] : 0;
  struct Mapped { int ours, child, from, to, next = -1; };  // next: end of the child's bone
  std::vector<Mapped> links;
  for (const Link& l : kLinks) {
    const char* f = cmu01 ? l.from01 : l.from131;
    const char* t = cmu01 ? l.to01 : l.to131;
    int o = sk.find_joint(l.ours), c = child_of(l.ours) ? sk.find_joint(child_of(l.ours)) : -1;
    if (o < 0 || c < 0) return Error{std::string(file), "", std::string("target skeleton lacks joint ") + l.ours};
    if (!by_name.count(f) || !by_name.count(t)) continue;  // not in this file: stays neutral
    links.push_back({o, c, by_name[f], by_name[t]});
  }
  std::sort(links.begin(), links.end(), [](const Mapped& a, const Mapped& b) { return a.ours < b.ours; });
  // Hips and shoulders also turn so that the knee's and elbow's hinge lies in the plane the BVH
  // limb bends in (their own DOFs bend only about that hinge).
  for (Mapped& m : links)
    for (const Mapped& c : links)
      if (c.ours == m.child && c.from == m.to && sk.joints()[c.ours].dofs.size() <= 2) m.next = c.to;

  const size_t nb = bvh.joints.size();
  std::vector<glm::mat3> brot(nb);
  std::vector<glm::vec3> bpos(nb);
  auto bvh_fk = [&](const std::vector<float>* frame) { bvh_forward(bvh, frame, brot, bpos); };
  // Scale: our hip-to-ankle length over the BVH's, in the rest poses.
  bvh_fk(nullptr);
  int bl_hip = by_name[cmu01 ? "LeftUpLeg" : "LeftHip"], bl_ankle = by_name[cmu01 ? "LeftFoot" : "LeftAnkle"];
  float bvh_leg = glm::length(bpos[bl_hip] - bpos[bl_ankle]);
  auto rest = sk.world_transforms(sk.neutral());
  float our_leg = glm::length(glm::vec3(rest[sk.find_joint("l_hip")][3] - rest[sk.find_joint("l_ankle")][3]));
  if (!(bvh_leg > 0)) return Error{std::string(file), "HIERARCHY", "the BVH leg has no length"};
  float scale = our_leg / bvh_leg;
  // Ground: the lowest ankle in the first frame sits where ours does in the neutral posture.
  bvh_fk(&bvh.frames[0]);
  float bvh_ground = std::min(bpos[bl_ankle].y, bpos[by_name[cmu01 ? "RightFoot" : "RightAnkle"]].y);
  float our_ankle_y = rest[sk.find_joint("l_ankle")][3].y;
  glm::vec3 root_rest = sk.joints()[0].offset;

  Clip clip;
  clip.name = name;
  clip.fps = 1.0f / bvh.frame_time;
  clip.loops = false;
  const modeler::Joint& root = sk.joints()[0];
  modeler::Posture prev = sk.neutral();
  std::vector<glm::mat4> w(sk.joints().size());
  for (const auto& frame : bvh.frames) {
    bvh_fk(&frame);
    modeler::Posture p = prev;
    // Root: translation scaled, rotation fitted to the hips' world rotation.
    glm::vec3 hp = bpos[hips];
    glm::vec3 target_root(hp.x * scale, (hp.y - bvh_ground) * scale + our_ankle_y, hp.z * scale);
    for (size_t k = 0; k < root.dofs.size(); ++k) {
      const auto& d = root.dofs[k];
      if (d.type == modeler::DofType::kTranslation)
        p[root.first_dof + k] = std::clamp(glm::dot(target_root - root_rest, d.axis), d.min, d.max);
    }
    {
      // Fit the root's rotation DOFs to two directions of the hips' frame.
      glm::mat3 R = brot[hips];
      std::vector<int> rot;
      for (size_t k = 0; k < root.dofs.size(); ++k)
        if (root.dofs[k].type == modeler::DofType::kRotation) rot.push_back(static_cast<int>(k));
      modeler::Joint rj;
      for (int k : rot) rj.dofs.push_back(root.dofs[k]);
      float v[6] = {};
      for (size_t k = 0; k < rot.size(); ++k) v[k] = p[root.first_dof + rot[k]];
      for (int pass = 0; pass < 2; ++pass) {
        fit_direction(rj, glm::vec3(0, 0, 1), R * glm::vec3(0, 0, 1), v);
        fit_direction(rj, glm::vec3(0, 1, 0), R * glm::vec3(0, 1, 0), v);
      }
      for (size_t k = 0; k < rot.size(); ++k) p[root.first_dof + rot[k]] = v[k];
    }
    // Every mapped joint, parents first: point our link along the BVH bone.
    for (const Mapped& m : links) {
      sk.world_transforms(p, w);
      const modeler::Joint& j = sk.joints()[m.ours];
      glm::mat3 parent_rot = j.parent >= 0 ? glm::mat3(w[j.parent]) : glm::mat3(1.0f);
      glm::vec3 dw = bpos[m.to] - bpos[m.from];
      if (glm::length(dw) < 1e-6f) continue;
      glm::vec3 d0 = glm::normalize(sk.joints()[m.child].offset);
      glm::vec3 dl = glm::normalize(glm::transpose(parent_rot) * glm::normalize(dw));
      std::vector<float> v(j.dofs.size());
      for (size_t k = 0; k < j.dofs.size(); ++k) v[k] = p[j.first_dof + k];
      glm::vec3 vecs[2] = {d0, {}}, targets[2] = {dl, {}};
      float weights[2] = {1.0f, 0.0f};
      int count = 1;
      if (m.next >= 0) {
        glm::vec3 n = glm::cross(glm::normalize(dw), bpos[m.next] - bpos[m.to]);
        float len = glm::length(n);
        if (len > 0.15f * glm::length(bpos[m.next] - bpos[m.to])) {  // bent enough to define a plane
          const auto& hinge = sk.joints()[m.child].dofs.front();
          vecs[1] = hinge.axis;
          targets[1] = glm::transpose(parent_rot) * (n / len);
          weights[1] = 0.7f;
          count = 2;
        }
      }
      fit_vectors(j, count, vecs, targets, weights, v.data());
      for (size_t k = 0; k < j.dofs.size(); ++k) p[j.first_dof + k] = v[k];
    }
    sk.clamp(p);
    clip.frames.push_back(p);
    prev = p;
  }
  return clip;
}

Result<Clip> load_bvh(const std::string& path, const modeler::Skeleton& target) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return Error{path, "", "cannot open file (does it exist?)"};
  std::stringstream ss;
  ss << in.rdbuf();
  std::string text = ss.str();
  auto bvh = parse_bvh(text, path);
  if (!bvh) return bvh.error();
  return retarget(*bvh, target, std::filesystem::path(path).stem().string(), path);
}

}  // namespace bb::motion
