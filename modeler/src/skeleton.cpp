#include "bb/modeler/skeleton.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <unordered_map>

#include <glm/gtc/matrix_transform.hpp>

#include "json_util.h"

namespace bb::modeler {

using namespace detail;

int Skeleton::find_joint(std::string_view joint_name) const {
  for (size_t i = 0; i < joints_.size(); ++i)
    if (joints_[i].name == joint_name) return static_cast<int>(i);
  return -1;
}

int Skeleton::find_dof(std::string_view full_name) const {
  auto dot = full_name.find('.');
  if (dot == std::string_view::npos) return -1;
  int j = find_joint(full_name.substr(0, dot));
  if (j < 0) return -1;
  auto dn = full_name.substr(dot + 1);
  const Joint& jt = joints_[j];
  for (size_t k = 0; k < jt.dofs.size(); ++k)
    if (jt.dofs[k].name == dn) return jt.first_dof + static_cast<int>(k);
  return -1;
}

const Dof& Skeleton::dof(int index) const {
  assert(index >= 0 && index < dof_count_);
  const Joint& j = joints_[dof_joint_[index]];
  return j.dofs[index - j.first_dof];
}

Posture Skeleton::posture(std::string_view posture_name) const {
  Posture p = neutral();
  for (size_t i = 0; i < posture_names_.size(); ++i)
    if (posture_names_[i] == posture_name)
      for (auto [d, v] : postures_[i]) p[d] = v;
  return p;
}

int Skeleton::clamp(Posture& p) const {
  assert(static_cast<int>(p.size()) == dof_count_);
  int changed = 0;
  for (int i = 0; i < dof_count_; ++i) {
    const Dof& d = dof(i);
    float c = std::clamp(p[i], d.min, d.max);
    if (c != p[i]) { p[i] = c; ++changed; }
  }
  return changed;
}

bool Skeleton::within_limits(const Posture& p, float eps) const {
  if (static_cast<int>(p.size()) != dof_count_) return false;
  for (int i = 0; i < dof_count_; ++i) {
    const Dof& d = dof(i);
    if (!(p[i] >= d.min - eps && p[i] <= d.max + eps)) return false;
  }
  return true;
}

glm::mat4 Skeleton::local_transform(int j, const Posture& p) const {
  const Joint& jt = joints_[j];
  glm::vec3 t = jt.offset;
  glm::mat4 r(1.0f);
  for (size_t k = 0; k < jt.dofs.size(); ++k) {
    const Dof& d = jt.dofs[k];
    float v = p[jt.first_dof + k];
    if (d.type == DofType::kTranslation) {
      t += d.axis * v;
    } else if (v != 0.0f) {
      r = r * glm::rotate(glm::mat4(1.0f), v, d.axis);
    }
  }
  r[3] = glm::vec4(t, 1.0f);
  return r;
}

void Skeleton::world_transforms(const Posture& p, std::span<glm::mat4> out) const {
  assert(static_cast<int>(p.size()) == dof_count_ && out.size() == joints_.size());
  for (size_t j = 0; j < joints_.size(); ++j) {
    glm::mat4 l = local_transform(static_cast<int>(j), p);
    out[j] = joints_[j].parent < 0 ? l : out[joints_[j].parent] * l;
  }
}

std::vector<glm::mat4> Skeleton::world_transforms(const Posture& p) const {
  std::vector<glm::mat4> out(joints_.size());
  world_transforms(p, out);
  return out;
}

glm::vec3 Skeleton::ta() const {
  int j = find_joint("vl5");
  if (j < 0) j = 0;
  auto w = world_transforms(posture("max_extent"));
  return glm::vec3(w[j][3]);
}


Result<Skeleton> parse_skeleton(std::string_view text, std::string_view file) {
  Skeleton sk;
  try {
    json doc = parse_text(text);
    const std::string root = "$";
    if (!doc.is_object()) fail(root, "expected an object at the top level");
    if (auto it = doc.find("name"); it != doc.end()) sk.name = string(*it, at(root, "name"));
    if (auto it = doc.find("limits_source"); it != doc.end())
      sk.limits_source = string(*it, at(root, "limits_source"));
    const json& jj = array(member(doc, root, "joints"), at(root, "joints"));
    if (jj.empty()) fail(at(root, "joints"), "a skeleton needs at least one joint");

    struct RawJoint { Joint j; std::string parent; std::string path; };
    std::vector<RawJoint> raw;
    std::unordered_map<std::string, int> by_name;
    for (size_t i = 0; i < jj.size(); ++i) {
      std::string p = at(at(root, "joints"), i);
      RawJoint r;
      r.path = p;
      r.j.name = string(member(jj[i], p, "name"), at(p, "name"));
      if (r.j.name.empty()) fail(at(p, "name"), "joint name is empty");
      if (r.j.name.find('.') != std::string::npos) fail(at(p, "name"), "joint name may not contain '.'");
      if (by_name.count(r.j.name)) fail(at(p, "name"), "duplicate joint name \"" + r.j.name + "\"");
      by_name[r.j.name] = static_cast<int>(i);
      const json& par = member(jj[i], p, "parent");
      if (!par.is_null()) r.parent = string(par, at(p, "parent"));
      r.j.offset = vec3(member(jj[i], p, "offset"), at(p, "offset"));
      if (auto it = jj[i].find("dofs"); it != jj[i].end()) {
        const json& dd = array(*it, at(p, "dofs"));
        for (size_t k = 0; k < dd.size(); ++k) {
          std::string dp = at(at(p, "dofs"), k);
          Dof d;
          d.name = string(member(dd[k], dp, "name"), at(dp, "name"));
          std::string type = string(member(dd[k], dp, "type"), at(dp, "type"));
          glm::vec3 axis = vec3(member(dd[k], dp, "axis"), at(dp, "axis"));
          float len = glm::length(axis);
          if (!(len > 1e-6f)) fail(at(dp, "axis"), "axis must be a non-zero vector");
          d.axis = axis / len;
          if (type == "rotation") {
            d.type = DofType::kRotation;
            d.min = glm::radians(static_cast<float>(number(member(dd[k], dp, "min_deg"), at(dp, "min_deg"))));
            d.max = glm::radians(static_cast<float>(number(member(dd[k], dp, "max_deg"), at(dp, "max_deg"))));
          } else if (type == "translation") {
            d.type = DofType::kTranslation;
            d.min = static_cast<float>(number(member(dd[k], dp, "min_m"), at(dp, "min_m")));
            d.max = static_cast<float>(number(member(dd[k], dp, "max_m"), at(dp, "max_m")));
          } else {
            fail(at(dp, "type"), "unknown DOF type \"" + type + "\" (expected rotation or translation)");
          }
          if (d.min > d.max) fail(dp, "limit min > max for DOF \"" + d.name + "\"");
          for (const Dof& o : r.j.dofs)
            if (o.name == d.name) fail(at(dp, "name"), "duplicate DOF name \"" + d.name + "\"");
          r.j.dofs.push_back(d);
        }
      }
      raw.push_back(std::move(r));
    }
    // Resolve parents, find the single root, detect cycles, order parents before children.
    std::vector<int> parent(raw.size(), -1);
    int roots = 0;
    for (size_t i = 0; i < raw.size(); ++i) {
      if (raw[i].parent.empty()) { ++roots; continue; }
      auto it = by_name.find(raw[i].parent);
      if (it == by_name.end())
        fail(at(raw[i].path, "parent"), "unknown joint \"" + raw[i].parent + "\"");
      parent[i] = it->second;
    }
    for (size_t i = 0; i < raw.size(); ++i) {
      size_t steps = 0;
      for (int k = static_cast<int>(i); k >= 0; k = parent[k])
        if (++steps > raw.size())
          fail(at(raw[i].path, "parent"), "joint cycle through \"" + raw[i].j.name + "\"");
    }
    if (roots != 1)
      fail(at(root, "joints"), "expected exactly one root joint (parent null), found " + std::to_string(roots));
    std::vector<int> order, depth(raw.size());
    for (size_t i = 0; i < raw.size(); ++i) {
      int d = 0;
      for (int k = parent[i]; k >= 0; k = parent[k]) ++d;
      depth[i] = d;
      order.push_back(static_cast<int>(i));
    }
    // File order when it already lists parents first; otherwise order by depth.
    std::stable_sort(order.begin(), order.end(), [&](int a, int b) { return depth[a] < depth[b]; });
    bool file_order_ok = true;
    for (size_t i = 0; i < raw.size(); ++i)
      if (parent[i] >= static_cast<int>(i)) file_order_ok = false;
    if (file_order_ok) for (size_t i = 0; i < raw.size(); ++i) order[i] = static_cast<int>(i);
    std::vector<int> new_index(raw.size());
    for (size_t i = 0; i < order.size(); ++i) new_index[order[i]] = static_cast<int>(i);
    int dofs = 0;
    for (int oi : order) {
      Joint j = raw[oi].j;
      j.parent = parent[oi] < 0 ? -1 : new_index[parent[oi]];
      j.first_dof = dofs;
      for (size_t k = 0; k < j.dofs.size(); ++k) sk.dof_joint_.push_back(static_cast<int>(sk.joints_.size()));
      dofs += static_cast<int>(j.dofs.size());
      sk.joints_.push_back(std::move(j));
    }
    sk.dof_count_ = dofs;
    // Named postures: {"name": {"joint.dof": degrees or metres}}.
    if (auto it = doc.find("postures"); it != doc.end()) {
      std::string pp = at(root, "postures");
      if (!it->is_object()) fail(pp, "expected an object of named postures");
      for (auto& [pname, vals] : it->items()) {
        std::string vp = at(pp, pname);
        if (!vals.is_object()) fail(vp, "expected an object of \"joint.dof\": value");
        std::vector<std::pair<int, float>> sparse;
        for (auto& [dname, v] : vals.items()) {
          int d = sk.find_dof(dname);
          if (d < 0) fail(at(vp, dname), "unknown DOF \"" + dname + "\" (expected \"joint.dof\")");
          float value = static_cast<float>(number(v, at(vp, dname)));
          const Dof& dof = sk.dof(d);
          if (dof.type == DofType::kRotation) value = glm::radians(value);
          if (value < dof.min - 1e-6f || value > dof.max + 1e-6f)
            fail(at(vp, dname), "value outside the DOF's limits");
          sparse.emplace_back(d, value);
        }
        sk.posture_names_.push_back(pname);
        sk.postures_.push_back(std::move(sparse));
      }
    }
  } catch (const JsonError& e) {
    return Error{std::string(file), e.where, e.reason};
  }
  return sk;
}

Result<Skeleton> load_skeleton(const std::string& path) {
  auto text = read_file(path);
  if (!text) return text.error();
  return parse_skeleton(*text, path);
}

}  // namespace bb::modeler
