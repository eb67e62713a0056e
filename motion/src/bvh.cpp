#include "bb/motion/bvh.h"

#include <algorithm>
#include <array>
#include <cctype>
#include <charconv>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <optional>
#include <span>
#include <sstream>

#include <glm/gtc/constants.hpp>
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

// The lines of the text from `pos` on; `line` is the number of the line starting at `pos` (after the
// last line, the number the next one would have).
struct Lines {
  std::string_view text;
  size_t pos = 0;
  int line = 1;
  bool next(std::string_view& out, int& number) {
    if (pos >= text.size()) return false;
    size_t e = text.find('\n', pos);
    if (e == std::string_view::npos) e = text.size();
    out = text.substr(pos, e - pos);
    number = line++;
    pos = e + 1;
    return true;
  }
};

bool is_space(char c) { return std::isspace(static_cast<unsigned char>(c)) != 0; }

bool blank(std::string_view s) { return std::all_of(s.begin(), s.end(), is_space); }

// The whitespace-separated words of one line.
void split(std::string_view s, std::vector<std::string_view>& words) {
  words.clear();
  for (size_t i = 0; i < s.size();) {
    if (is_space(s[i])) { ++i; continue; }
    size_t b = i;
    while (i < s.size() && !is_space(s[i])) ++i;
    words.push_back(s.substr(b, i - b));
  }
}

std::string_view first_word(std::string_view s) {
  size_t b = 0;
  while (b < s.size() && is_space(s[b])) ++b;
  size_t e = b;
  while (e < s.size() && !is_space(s[e])) ++e;
  return s.substr(b, std::min<size_t>(e - b, 40));
}

struct ParseError {
  int line;
  std::string reason;
};

float to_float(std::string_view s, int line, const char* what) {
  float v = 0;
  std::string t(s);
  char* end = nullptr;
  v = std::strtof(t.c_str(), &end);
  // (The whole word: a NUL byte inside it would end strtof's reading early.)
  if (t.empty() || end != t.data() + t.size() || !std::isfinite(v))
    throw ParseError{line, std::string("expected a number for ") + what + ", got \"" + t + "\""};
  return v;
}

// Offsets and channel values are lengths (any unit) or degrees: beyond this they are damage, and they
// would overflow the forward kinematics (an OFFSET of 1e30 makes every retargeted posture NaN).
constexpr float kMaxValue = 1e6f;
float to_value(std::string_view s, int line, const char* what) {
  const float v = to_float(s, line, what);
  if (!(std::abs(v) <= kMaxValue))
    throw ParseError{line, std::string(what) + " " + std::string(s) + " is out of range (at most 1e6 in size)"};
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
  if (text.substr(0, 3) == "\xEF\xBB\xBF") lx.pos = 3;  // a UTF-8 byte order mark
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
      for (int k = 0; k < 3; ++k) j.offset[k] = to_value(lx.next(), lx.line, "OFFSET");
      tok = lx.next();
      if (!j.end_site) {
        if (tok != "CHANNELS") throw ParseError{lx.line, "expected CHANNELS in " + j.name};
        std::string_view n = lx.next();
        const float count_f = to_float(n, lx.line, "the channel count");
        if (!(count_f >= 0 && count_f <= 6) || count_f != std::floor(count_f))
          throw ParseError{lx.line, "channel count must be 0..6, got " + std::string(n)};
        const int count = static_cast<int>(count_f);
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
    // Without channels a frame holds nothing, so nothing would bound the frame count.
    if (channels == 0) throw ParseError{lx.line, "no joint has channels: the file holds no motion"};
    if (lx.next() != "Frames:") throw ParseError{lx.line, "expected \"Frames:\""};
    std::string_view nf = lx.next();
    float frames_f = to_float(nf, lx.line, "the frame count");
    if (frames_f < 1 || frames_f != std::floor(frames_f)) throw ParseError{lx.line, "frame count must be a positive integer"};
    if (frames_f >= 2147483648.0f) throw ParseError{lx.line, "frame count " + std::string(nf) + " is too large"};
    int frames = static_cast<int>(frames_f);
    if (lx.next() != "Frame" || lx.next() != "Time:") throw ParseError{lx.line, "expected \"Frame Time:\""};
    out.frame_time = to_float(lx.next(), lx.line, "the frame time");
    if (!(out.frame_time > 0)) throw ParseError{lx.line, "frame time must be positive"};
    if (!(out.frame_time >= 1e-6f && out.frame_time <= 1e6f))
      throw ParseError{lx.line, "frame time must be from 1e-6 to 1e6 seconds"};
    // Frames are read line by line: a frame is one line holding exactly `channels` values (the CMU
    // conversions write them so; a short or long row would otherwise shift every later frame's channels).
    // Blank lines hold no frame and are skipped; a row beyond the declared count is an error.
    // Frames are added as they are read: the count is a claim, and a damaged one must not allocate.
    Lines rows{text, lx.pos, lx.line};
    std::string_view row;
    int row_line = 0;
    if (rows.next(row, row_line) && !blank(row))
      throw ParseError{row_line, "unexpected \"" + std::string(first_word(row)) +
                                     "\" after the frame time (frames start on the next line)"};
    std::vector<std::string_view> words;
    for (int f = 0; f < frames; ++f) {
      do {
        if (!rows.next(row, row_line))
          throw ParseError{rows.line, "file ends before frame " + std::to_string(f + 1) + " of " +
                                          std::to_string(frames) + " (truncated?)"};
      } while (blank(row));
      split(row, words);
      if (words.size() != static_cast<size_t>(channels))
        throw ParseError{row_line, "frame " + std::to_string(f + 1) + " has " + std::to_string(words.size()) +
                                       " values, expected " + std::to_string(channels) +
                                       " (one per channel the hierarchy declares)"};
      out.frames.emplace_back(channels);
      for (int c = 0; c < channels; ++c) out.frames[f][c] = to_value(words[c], row_line, "a channel value");
    }
    while (rows.next(row, row_line))
      if (!blank(row))
        throw ParseError{row_line, "a frame beyond the " + std::to_string(frames) + " that \"Frames:\" declares"};
  } catch (const ParseError& e) {
    return Error{std::string(file), "line " + std::to_string(e.line), e.reason};
  }
  return out;
}

namespace {

// The BVH joints the retargeting reads, by role, and the names the common BVH conventions give
// them: CMU's conversions (LeftUpLeg/LeftLeg/... and LeftHip/LeftKnee/...), the Daz-friendly
// release (hip, abdomen, lThigh, lShin, lShldr, ...), the original ASF names (lfemur, ltibia,
// lhumerus, ...), Mixamo (mixamorig:LeftUpLeg, ...) and engine-style suffixes (thigh_l, ...).
// Names are compared normalized (see normalize_name). In a pattern '*' stands for the side:
// "left" or "l" (left roles), "right" or "r" (right roles). Roles are resolved in this order and
// a BVH joint serves one role only, so an ambiguous name ("LeftShoulder": the collar in one
// convention, the upper arm in another) goes to the first role still open.
enum Role {
  kHips, kSpine0, kSpine1, kNeck0, kNeck1, kHead,
  kLCollar, kLUpperArm, kLForearm, kLWrist, kLFingers, kLThigh, kLShin, kLFoot, kLToe, kLToeEnd,
  kRCollar, kRUpperArm, kRForearm, kRWrist, kRFingers, kRThigh, kRShin, kRFoot, kRToe, kRToeEnd,
  kRoleCount
};
struct RoleNames {
  Role role;
  std::vector<const char*> names;
};
const std::vector<RoleNames>& role_names() {
  static const std::vector<RoleNames> central = {
      {kHips, {"hips", "hip", "pelvis", "root"}},
      {kSpine0, {"lowerback", "abdomen", "spine", "spine01", "waist"}},
      {kSpine1, {"chest", "spine", "thorax", "spine1", "spine02", "upperback", "spine2"}},
      {kNeck0, {"lowerneck", "neck", "neck01"}},
      {kNeck1, {"neck1", "upperneck", "neck02", "neck2", "neck"}},
      {kHead, {"head"}},
  };
  static const std::vector<RoleNames> side = {  // left roles; right ones are offset
      {kLCollar, {"*collar", "*clavicle", "clavicle*", "*shoulder"}},
      {kLUpperArm, {"*arm", "*uparm", "*upperarm", "upperarm*", "*shldr", "*humerus", "*shoulder"}},
      {kLForearm, {"*forearm", "forearm*", "*elbow", "*lowerarm", "lowerarm*", "*radius"}},
      {kLWrist, {"*wrist", "*hand", "hand*"}},
      {kLFingers, {"*fingerbase", "*hand", "*handmiddle1", "*mid1", "*middle1", "middle01*", "*fingers"}},
      {kLThigh, {"*upleg", "*thigh", "thigh*", "*upperleg", "upperleg*", "*femur", "*hip"}},
      {kLShin, {"*leg", "*shin", "*knee", "*lowerleg", "lowerleg*", "calf*", "*calf", "*tibia"}},
      {kLFoot, {"*foot", "foot*", "*ankle"}},
      {kLToe, {"*toebase", "*toe", "*toes", "ball*", "toe*"}},
      {kLToeEnd, {}},  // the toe's first child (its end site)
  };
  static const std::vector<RoleNames> all = [] {
    std::vector<RoleNames> v = central;
    for (int s = 0; s < 2; ++s)
      for (const RoleNames& r : side) v.push_back({Role(r.role + s * (kRCollar - kLCollar)), r.names});
    return v;
  }();
  return all;
}
bool is_right(Role r) { return r >= kRCollar; }

// Lower case, without a namespace prefix ("mixamorig:") and without '_', '-', '.', ' '.
std::string normalize_name(const std::string& name) {
  std::string out;
  size_t colon = name.rfind(':');
  for (size_t i = colon == std::string::npos ? 0 : colon + 1; i < name.size(); ++i) {
    char c = name[i];
    if (c == '_' || c == '-' || c == '.' || c == ' ') continue;
    out += static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  }
  return out;
}

// BVH joint index per role, -1 where the file has none (the fingers' and toes' roles fall back
// to the first child of the wrist and foot, an end site if need be).
std::array<int, kRoleCount> find_roles(const BvhFile& bvh) {
  std::map<std::string, int> by_name;
  for (size_t i = 0; i < bvh.joints.size(); ++i)
    if (!bvh.joints[i].end_site) by_name.emplace(normalize_name(bvh.joints[i].name), static_cast<int>(i));
  std::array<int, kRoleCount> at;
  at.fill(-1);
  std::vector<char> used(bvh.joints.size(), 0);
  for (const RoleNames& r : role_names()) {
    const char* sides[2][2] = {{"left", "l"}, {"right", "r"}};
    for (const char* pattern : r.names) {
      std::string p(pattern);
      size_t star = p.find('*');
      for (int k = 0; k < (star == std::string::npos ? 1 : 2) && at[r.role] < 0; ++k) {
        std::string n = star == std::string::npos ? p : p.substr(0, star) + sides[is_right(r.role)][k] + p.substr(star + 1);
        auto it = by_name.find(n);
        if (it != by_name.end() && !used[it->second]) {
          at[r.role] = it->second;
          used[it->second] = 1;
        }
      }
      if (at[r.role] >= 0) break;
    }
  }
  if (at[kHips] < 0 && !bvh.joints.empty()) at[kHips] = 0;  // the root
  auto first_child = [&](int j) {
    for (size_t i = 0; i < bvh.joints.size(); ++i)
      if (bvh.joints[i].parent == j) return static_cast<int>(i);
    return -1;
  };
  for (int s = 0; s < 2; ++s) {
    int o = s * (kRCollar - kLCollar);
    if (at[kLFingers + o] < 0 && at[kLWrist + o] >= 0) at[kLFingers + o] = first_child(at[kLWrist + o]);
    if (at[kLToe + o] < 0 && at[kLFoot + o] >= 0) at[kLToe + o] = first_child(at[kLFoot + o]);
    if (at[kLToe + o] >= 0) at[kLToeEnd + o] = first_child(at[kLToe + o]);
  }
  return at;
}

// Our joint -> the BVH bone (start role, end role) it follows; `alt` is the end when `to` is
// missing (a neck of one segment).
struct Link {
  const char* ours;
  Role from, to;
  Role alt = kRoleCount;
};
const Link kLinks[] = {
    {"vl5", kSpine0, kSpine1},
    {"vt10", kSpine1, kNeck0},
    {"vc7", kNeck0, kNeck1, kHead},
    {"skullbase", kNeck1, kHead},
    {"l_sternoclavicular", kLCollar, kLUpperArm},
    {"l_shoulder", kLUpperArm, kLForearm},
    {"l_elbow", kLForearm, kLWrist},
    {"l_wrist", kLWrist, kLFingers},
    {"r_sternoclavicular", kRCollar, kRUpperArm},
    {"r_shoulder", kRUpperArm, kRForearm},
    {"r_elbow", kRForearm, kRWrist},
    {"r_wrist", kRWrist, kRFingers},
    {"l_hip", kLThigh, kLShin},
    {"l_knee", kLShin, kLFoot},
    {"l_ankle", kLFoot, kLToe},
    {"l_metatarsophalangeal", kLToe, kLToeEnd},
    {"r_hip", kRThigh, kRShin},
    {"r_knee", kRShin, kRFoot},
    {"r_ankle", kRFoot, kRToe},
    {"r_metatarsophalangeal", kRToe, kRToeEnd},
};
// Our child joint whose direction from `ours` is the link.
const char* child_of(const std::string& ours) {
  static const std::map<std::string, const char*> m = {
      {"vl5", "vt10"}, {"vt10", "vc7"}, {"vc7", "skullbase"}, {"skullbase", "skull_tip"},
      {"l_sternoclavicular", "l_shoulder"}, {"l_shoulder", "l_elbow"}, {"l_elbow", "l_wrist"}, {"l_wrist", "l_middle1"},
      {"r_sternoclavicular", "r_shoulder"}, {"r_shoulder", "r_elbow"}, {"r_elbow", "r_wrist"}, {"r_wrist", "r_middle1"},
      {"l_hip", "l_knee"}, {"l_knee", "l_ankle"}, {"l_ankle", "l_metatarsophalangeal"},
      {"r_hip", "r_knee"}, {"r_knee", "r_ankle"}, {"r_ankle", "r_metatarsophalangeal"},
      {"l_metatarsophalangeal", "l_toe_tip"}, {"r_metatarsophalangeal", "r_toe_tip"}};
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

// Our feet's points that must stay above the floor (y = 0), the toe joint, and the root's vertical DOF.
struct Floor {
  int ankle[2], ball[2], tip[2];
  int ty;  // posture index of the root's Y translation
};
std::optional<Floor> find_floor(const modeler::Skeleton& sk) {
  Floor f{};
  const char* side[2] = {"l_", "r_"};
  for (int s = 0; s < 2; ++s) {
    f.ankle[s] = sk.find_joint(std::string(side[s]) + "ankle");
    f.ball[s] = sk.find_joint(std::string(side[s]) + "metatarsophalangeal");
    f.tip[s] = sk.find_joint(std::string(side[s]) + "toe_tip");
    if (f.ankle[s] < 0 || f.ball[s] < 0 || f.tip[s] < 0) return std::nullopt;
    if (sk.joints()[f.ball[s]].dofs.size() != 1 || sk.joints()[f.ball[s]].parent != f.ankle[s] ||
        sk.joints()[f.tip[s]].parent != f.ball[s])
      return std::nullopt;
  }
  f.ty = -1;
  const modeler::Joint& root = sk.joints()[0];
  for (size_t k = 0; k < root.dofs.size(); ++k)
    if (root.dofs[k].type == modeler::DofType::kTranslation && root.dofs[k].axis == glm::vec3(0, 1, 0))
      f.ty = root.first_dof + static_cast<int>(k);
  if (f.ty < 0) return std::nullopt;
  return f;
}

// The captured feet go below the floor where our joint limits differ from the actor's (our ankle
// dorsiflexes 45 degrees, the weight-bearing range: a deeper crouch on flat feet points our toes
// into the floor; at AAOS's active 20 degrees, 01_01's crouch did) and where the capture itself
// does (toe markers). A toe tip below the floor extends its toe joint as far as that lifts it;
// then, if any foot point is still below, the whole body rises by that much.
void keep_above_floor(const modeler::Skeleton& sk, const Floor& fl, modeler::Posture& p, std::span<glm::mat4> w) {
  sk.world_transforms(p, w);
  for (int s = 0; s < 2; ++s) {
    const modeler::Joint& ball = sk.joints()[fl.ball[s]];
    const glm::vec3 tip_offset = sk.joints()[fl.tip[s]].offset;
    const glm::mat3 ankle_rot(w[fl.ankle[s]]);
    const glm::vec3 ball_pos(w[fl.ball[s]][3]);
    auto tip_y = [&](float v) { return (ball_pos + ankle_rot * dof_rotation(ball, &v) * tip_offset).y; };
    float& v = p[ball.first_dof];
    if (tip_y(v) >= 0) continue;
    // The extension that lifts the tip (on either side of the current value), within the limits.
    const float hi = tip_y(ball.dofs[0].max) > tip_y(ball.dofs[0].min) ? ball.dofs[0].max : ball.dofs[0].min;
    if (tip_y(hi) <= tip_y(v)) continue;
    if (tip_y(hi) < 0) {
      v = hi;
      continue;
    }
    float a = v, b = hi;  // tip below at a, above at b
    for (int it = 0; it < 20; ++it) {
      const float m = 0.5f * (a + b);
      (tip_y(m) < 0 ? a : b) = m;
    }
    v = b;
  }
  sk.world_transforms(p, w);
  float low = 0;
  for (int s = 0; s < 2; ++s)
    for (int j : {fl.ankle[s], fl.ball[s], fl.tip[s]}) low = std::min(low, w[j][3].y);
  p[fl.ty] -= low;
}

}  // namespace

std::vector<glm::vec3> world_positions(const BvhFile& bvh, size_t frame) {
  std::vector<glm::mat3> rot(bvh.joints.size());
  std::vector<glm::vec3> pos(bvh.joints.size());
  bvh_forward(bvh, frame < bvh.frames.size() ? &bvh.frames[frame] : nullptr, rot, pos);
  return pos;
}

Result<Clip> retarget(const BvhFile& bvh, const modeler::Skeleton& sk, const std::string& name, std::string_view file) {
  const std::array<int, kRoleCount> at = find_roles(bvh);
  for (Role r : {kLThigh, kLShin, kLFoot, kRThigh, kRShin, kRFoot})
    if (at[r] < 0)
      return Error{std::string(file), "HIERARCHY",
                   "unknown joint naming: no thigh, shin and foot on both sides (tried the CMU, Daz, ASF, "
                   "Mixamo and thigh_l/calf_l names, e.g. LeftUpLeg/LeftLeg/LeftFoot, LeftHip/LeftKnee/LeftAnkle, "
                   "lThigh/lShin/lFoot, lfemur/ltibia/lfoot)"};
  const int hips = at[kHips];
  // next: end of the child's bone. For a foot, shin: the BVH's knee; bend: how much wider our rest
  // angle between shin and foot is than the BVH's, radians (see below).
  struct Mapped {
    int ours, child, from, to, next = -1, shin = -1;
    float bend = 0;
  };
  std::vector<Mapped> links;
  for (const Link& l : kLinks) {
    int o = sk.find_joint(l.ours), c = child_of(l.ours) ? sk.find_joint(child_of(l.ours)) : -1;
    if (o < 0 || c < 0) return Error{std::string(file), "", std::string("target skeleton lacks joint ") + l.ours};
    int f = at[l.from], t = at[l.to];
    if (t < 0 && l.alt != kRoleCount) t = at[l.alt];
    if (f < 0 || t < 0) continue;  // not in this file: stays neutral
    links.push_back({o, c, f, t});
  }
  std::sort(links.begin(), links.end(), [](const Mapped& a, const Mapped& b) { return a.ours < b.ours; });
  // Hips and shoulders also turn so that the knee's and elbow's hinge lies in the plane the BVH
  // limb bends in (their own DOFs bend only about that hinge).
  for (Mapped& m : links)
    for (const Mapped& c : links)
      if (c.ours == m.child && c.from == m.to && sk.joints()[c.ours].dofs.size() <= 2 && c.from != at[kLToe] &&
          c.from != at[kRToe])  // (not the ankle: the toes' bend is no plane to turn the foot into)
        m.next = c.to;

  const size_t nb = bvh.joints.size();
  std::vector<glm::mat3> brot(nb);
  std::vector<glm::vec3> bpos(nb);
  auto bvh_fk = [&](const std::vector<float>* frame) { bvh_forward(bvh, frame, brot, bpos); };
  // Scale: our hip-to-ankle length over the BVH's, in the rest poses.
  bvh_fk(nullptr);
  const int bl_hip = at[kLThigh], bl_ankle = at[kLFoot];
  float bvh_leg = glm::length(bpos[bl_hip] - bpos[bl_ankle]);
  auto rest = sk.world_transforms(sk.neutral());
  float our_leg = glm::length(glm::vec3(rest[sk.find_joint("l_hip")][3] - rest[sk.find_joint("l_ankle")][3]));
  // (In any unit a leg is longer than this; a shorter one would scale the root's travel past float's range.)
  if (!(bvh_leg > 1e-6f)) return Error{std::string(file), "HIERARCHY", "the BVH leg has no length"};
  float scale = our_leg / bvh_leg;
  // Feet: CMU's foot bone (ankle to toe base) points 10.5 degrees below the horizontal in its rest
  // pose, a flat-footed stance, 101-104 degrees from the shin; ours (ankle to ball) 20 below, 109
  // from the shin. Matched as directions, our flat foot came out toes up: standing in 01_01, toe
  // tips 1-2 cm above their flat height (3 cm once the ankle could dorsiflex past 20 degrees). A
  // foot keeps the source's angle to its shin plus the rest poses' difference (`bend`, radians; 5-8
  // degrees in CMU's clips), turned in the plane of the two bones.
  auto angle = [](glm::vec3 a, glm::vec3 b) {
    return std::acos(std::clamp(glm::dot(glm::normalize(a), glm::normalize(b)), -1.0f, 1.0f));
  };
  for (Mapped& m : links) {
    const int shin = m.from == at[kLFoot] ? at[kLShin] : m.from == at[kRFoot] ? at[kRShin] : -1;
    const int knee = sk.joints()[m.ours].parent;
    if (shin < 0 || knee < 0) continue;
    const glm::vec3 up_b = bpos[shin] - bpos[m.from], foot_b = bpos[m.to] - bpos[m.from];
    const glm::vec3 up_o(rest[knee][3] - rest[m.ours][3]),
        foot_o(rest[m.child][3] - rest[m.ours][3]);
    if (glm::length(glm::cross(glm::normalize(up_b), glm::normalize(foot_b))) < 0.1f)
      continue;  // no plane
    m.shin = shin;
    m.bend = angle(up_o, foot_o) - angle(up_b, foot_b);
  }
  // Ground: the lower ankle sits where ours does in the neutral posture, at the height the lower ankle
  // has in most frames (the median over the clip: one foot is down in most frames of a capture, and a
  // single frame may be a glitch; CMU's first frames often hold the ankles 0.3-0.8 units lower than
  // the standing that follows, which made the whole clip float 4 cm).
  std::vector<float> lower_ankle;
  lower_ankle.reserve(bvh.frames.size());
  for (const auto& frame : bvh.frames) {
    bvh_fk(&frame);
    lower_ankle.push_back(std::min(bpos[bl_ankle].y, bpos[at[kRFoot]].y));
  }
  std::nth_element(lower_ankle.begin(), lower_ankle.begin() + lower_ankle.size() / 2, lower_ankle.end());
  const float bvh_ground = lower_ankle[lower_ankle.size() / 2];
  float our_ankle_y = rest[sk.find_joint("l_ankle")][3].y;
  glm::vec3 root_rest = sk.joints()[0].offset;

  // Our hip joints' midpoint in the root's frame.
  const glm::vec3 our_hips_local =
      0.5f * (glm::vec3(rest[sk.find_joint("l_hip")][3]) + glm::vec3(rest[sk.find_joint("r_hip")][3])) -
      glm::vec3(rest[0][3]);
  // The root's rotation DOFs; yaw (Y), pitch (X), roll (Z) in this order are set in closed form.
  std::vector<int> root_rot;
  for (size_t k = 0; k < sk.joints()[0].dofs.size(); ++k)
    if (sk.joints()[0].dofs[k].type == modeler::DofType::kRotation) root_rot.push_back(static_cast<int>(k));
  const bool root_euler = [&] {
    if (root_rot.size() != 3) return false;
    const glm::vec3 axes[3] = {{0, 1, 0}, {1, 0, 0}, {0, 0, 1}};
    for (int k = 0; k < 3; ++k) {
      const auto& d = sk.joints()[0].dofs[root_rot[k]];
      if (glm::length(d.axis - axes[k]) > 1e-4f) return false;
      if (d.min > -glm::pi<float>() + 1e-3f || d.max < glm::pi<float>() - 1e-3f) {
        if (k != 1 || d.min > -glm::half_pi<float>() + 1e-3f || d.max < glm::half_pi<float>() - 1e-3f) return false;
      }
    }
    return true;
  }();

  const std::optional<Floor> floor = find_floor(sk);

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
    // Root rotation: the hips' world rotation, taken apart in the order of our root's rotation DOFs.
    // (Fitted by Gauss-Newton from the last frame it stayed at yaw 0 when the actor turned to face -Z:
    // at the opposite direction the gradient vanishes. Then the hips' twist clamped, the knees could not
    // bend in the captured plane, and the legs came out straight with the feet pointing down.)
    const glm::mat3 R = brot[hips];
    if (root_euler) {
      const float yaw = std::atan2(R[2][0], R[2][2]);
      const float pitch = std::asin(std::clamp(-R[2][1], -1.0f, 1.0f));
      const float roll = std::atan2(R[0][1], R[1][1]);
      p[root.first_dof + root_rot[0]] = yaw;
      p[root.first_dof + root_rot[1]] = pitch;
      p[root.first_dof + root_rot[2]] = roll;
    } else {
      // Another root: fit its rotation DOFs to two directions of the hips' frame.
      modeler::Joint rj;
      for (int k : root_rot) rj.dofs.push_back(root.dofs[k]);
      float v[6] = {};
      for (size_t k = 0; k < root_rot.size(); ++k) v[k] = p[root.first_dof + root_rot[k]];
      for (int pass = 0; pass < 2; ++pass) {
        fit_direction(rj, glm::vec3(0, 0, 1), R * glm::vec3(0, 0, 1), v);
        fit_direction(rj, glm::vec3(0, 1, 0), R * glm::vec3(0, 1, 0), v);
      }
      for (size_t k = 0; k < root_rot.size(); ++k) p[root.first_dof + root_rot[k]] = v[k];
    }
    // Root translation: our hip joints' midpoint goes where the BVH's is, scaled, over the ground. (The
    // BVH root itself sits higher above its hip joints than ours, ~11 cm scaled in CMU's against 4 cm:
    // placing the roots made standing clips float.)
    {
      std::vector<float> rv(root_rot.size());
      for (size_t k = 0; k < root_rot.size(); ++k) rv[k] = p[root.first_dof + root_rot[k]];
      modeler::Joint rj;
      for (int k : root_rot) rj.dofs.push_back(root.dofs[k]);
      const glm::vec3 hm = 0.5f * (bpos[at[kLThigh]] + bpos[at[kRThigh]]);
      const glm::vec3 target_hips(hm.x * scale, (hm.y - bvh_ground) * scale + our_ankle_y, hm.z * scale);
      const glm::vec3 target_root = target_hips - dof_rotation(rj, rv.data()) * our_hips_local;
      for (size_t k = 0; k < root.dofs.size(); ++k) {
        const auto& d = root.dofs[k];
        if (d.type == modeler::DofType::kTranslation)
          p[root.first_dof + k] = std::clamp(glm::dot(target_root - root_rest, d.axis), d.min, d.max);
      }
    }
    // Every mapped joint, parents first: point our link along the BVH bone.
    for (const Mapped& m : links) {
      sk.world_transforms(p, w);
      const modeler::Joint& j = sk.joints()[m.ours];
      glm::mat3 parent_rot = j.parent >= 0 ? glm::mat3(w[j.parent]) : glm::mat3(1.0f);
      glm::vec3 dw = bpos[m.to] - bpos[m.from];
      if (glm::length(dw) < 1e-6f) continue;
      if (m.shin >= 0) {  // a foot: away from its shin by the rest poses' difference
        const glm::vec3 up = bpos[m.shin] - bpos[m.from], axis = glm::cross(up, dw);
        if (glm::length(axis) > 0.1f * glm::length(up) * glm::length(dw))
          dw = glm::mat3(glm::rotate(glm::mat4(1.0f), m.bend, glm::normalize(axis))) * dw;
      }
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
    if (floor) keep_above_floor(sk, *floor, p, w);
    clip.frames.push_back(p);
    prev = p;
  }
  return clip;
}

Result<Clip> load_bvh(const std::string& path, const modeler::Skeleton& target) {
  // A directory opens and reads as an empty file on Linux: say what it is.
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec)) return Error{path, "", "is a directory, not a BVH file"};
  std::ifstream in(path, std::ios::binary);
  if (!in) return Error{path, "", "cannot open file (does it exist?)"};
  std::stringstream ss;
  ss << in.rdbuf();
  if (in.bad()) return Error{path, "", "read error"};
  std::string text = ss.str();
  auto bvh = parse_bvh(text, path);
  if (!bvh) return bvh.error();
  return retarget(*bvh, target, std::filesystem::path(path).stem().string(), path);
}

}  // namespace bb::motion
