// Model: baking the clips for the per-frame paths, the snapshot frame (Ta, radius) and the
// automatic choice of the posture-test pairs.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <limits>
#include <unordered_map>

#include "bb/runtime/animation.h"
#include "bb/runtime/model.h"

namespace bb::runtime {

int Model::find_clip(std::string_view clip_name) const {
  for (std::size_t i = 0; i < clips.size(); ++i)
    if (clips[i].name == clip_name) return static_cast<int>(i);
  return -1;
}

int Model::find_node(std::string_view node_name) const {
  for (std::size_t i = 0; i < nodes.size(); ++i)
    if (nodes[i].name == node_name) return static_cast<int>(i);
  return -1;
}

float Model::clip_duration(int clip) const {
  return clip >= 0 && clip < static_cast<int>(clips.size()) ? clips[clip].duration : 0.0f;
}

BakedSample BakedClip::sample_edges(float time) const {
  BakedSample s;
  // The grid frame at or before `time`, then over the edges' frames to the last frame at or before it.
  const float fx = std::min(time * rate, static_cast<float>(grid.size() - 1));
  int f = grid[static_cast<std::size_t>(fx)];
  while (f > 0 && times[f] > time) --f;
  while (f + 1 < frame_count && times[f + 1] <= time) ++f;
  s.f0 = f;
  s.f1 = std::min(f + 1, frame_count - 1);
  if (!stepped && s.f1 > s.f0) s.blend = std::clamp((time - times[f]) / (times[f + 1] - times[f]), 0.0f, 1.0f);
  return s;
}

void Model::set_posture_pairs(std::span<const PosturePair> pairs) {
  posture_pairs_.assign(pairs.begin(), pairs.end());
  if (posture_pairs_.empty()) posture_pairs_.push_back(PosturePair{});
  while (posture_pairs_.size() < kPosturePairs) posture_pairs_.push_back(posture_pairs_.back());
  posture_pairs_.resize(kPosturePairs);
  bake_posture();
}

Status Model::set_posture_pairs(std::span<const std::pair<std::string, std::string>> joint_names) {
  std::vector<PosturePair> pairs;
  for (const auto& [a, b] : joint_names) {
    int na = find_node(a), nb = find_node(b);
    if (na < 0) return Error{name, "", "no joint named \"" + a + "\""};
    if (nb < 0) return Error{name, "", "no joint named \"" + b + "\""};
    pairs.push_back(PosturePair{{na, glm::vec3(0.0f)}, {nb, glm::vec3(0.0f)}});
  }
  if (pairs.empty()) return Error{name, "", "no posture pairs given"};
  set_posture_pairs(pairs);
  return Ok{};
}

namespace {

// Frames sampled to measure a clip (bounds, variability): every baked frame up to `cap`.
int sample_stride(int frames, int cap) { return std::max(1, (frames + cap - 1) / cap); }

// Local transforms of baked frame `f` of `bc`, clip `clip` (-1: the rest pose).
void sample_frame(const Model& m, int clip, const BakedClip& bc, int f, std::span<Transform> locals) {
  if (bc.before_step[f]) sample_clip_before(m, clip, bc.times[f], locals);
  else sample_clip(m, clip, bc.times[f], locals);
}

// BakedClip's frames for clip `clip` (-1: the rest pose, one frame) of `duration` seconds at `rate`:
// times, before_step, grid and stepped (see BakedClip).
void lay_out_frames(const Model& m, int clip, float duration, float rate, BakedClip& bc) {
  const int grid_count = duration > 0.0f ? static_cast<int>(std::ceil(duration * rate - 1e-3f)) + 1 : 1;
  const std::vector<Channel> none;
  const std::vector<Channel>& channels = clip >= 0 ? m.clips[clip].channels : none;
  bc.stepped = !channels.empty() &&
               std::all_of(channels.begin(), channels.end(), [](const Channel& c) { return c.interpolation == Interpolation::kStep; });
  // The step edges: the keys where a STEP channel's value changes, inside (0, duration] (a key at
  // or before 0 holds from the start).
  std::vector<float> edges;
  for (const Channel& c : channels)
    if (c.interpolation == Interpolation::kStep)
      for (std::size_t k = 1; k < c.times.size(); ++k)
        if (c.values[k] != c.values[k - 1] && c.times[k] > 0.0f && c.times[k] <= duration) edges.push_back(c.times[k]);
  std::sort(edges.begin(), edges.end());
  edges.erase(std::unique(edges.begin(), edges.end()), edges.end());
  bc.times.clear();
  bc.before_step.clear();
  bc.grid.clear();
  auto add = [&](float t, bool before) {
    bc.times.push_back(t);
    bc.before_step.push_back(before ? 1 : 0);
  };
  // An edge's frames: the pose just before the key (the stepped clip's blend never reaches it), then
  // the pose at it unless grid frame `grid_time` is at that very time.
  auto add_edge = [&](float t, float grid_time) {
    if (!bc.stepped) add(t, true);
    if (t != grid_time) add(t, false);
  };
  std::size_t e = 0;
  for (int g = 0; g < grid_count; ++g) {
    const float t = std::min(static_cast<float>(g) / rate, duration);
    for (; e < edges.size() && edges[e] <= t; ++e) add_edge(edges[e], t);
    bc.grid.push_back(static_cast<int>(bc.times.size()));
    add(t, false);
  }
  for (; e < edges.size(); ++e) add_edge(edges[e], -1.0f);
  bc.frame_count = static_cast<int>(bc.times.size());
}

// Per node: whether it is a skin joint (a palette node), and whether one of its children is. The
// skeleton's end joints are the joints without a joint child.
struct SkeletonFlags {
  std::vector<bool> joint, parent_of_joint;
};
SkeletonFlags skeleton_flags(const Model& m) {
  SkeletonFlags f{std::vector<bool>(m.nodes.size(), false), std::vector<bool>(m.nodes.size(), false)};
  for (const auto& e : m.palette) f.joint[e.node] = true;
  for (std::size_t i = 0; i < m.nodes.size(); ++i)
    if (f.joint[i] && m.nodes[i].parent >= 0 && f.joint[m.nodes[i].parent]) f.parent_of_joint[m.nodes[i].parent] = true;
  return f;
}

// BakedClip::ground_speed from `track`: per grid frame, the skeleton root's place, then the `ends` end
// joints' places (model space); `height` the model's. Each frame's step of the body over its lowest
// end joint, along the steps' mean direction; the median of those speeds. (Of the medians of their
// lengths and of the means, this came closest on our walk, whose clip name gives its speed: 1.26
// against 1.20 m/s; the lengths' median gave 1.42, as the toes roll about the planted ankle.)
float ground_speed(const BakedClip& bc, const std::vector<glm::vec3>& track, std::size_t ends, float height) {
  const std::size_t stride = ends + 1;
  std::vector<glm::vec2> steps;
  glm::vec2 sum(0.0f);
  const int grid_count = static_cast<int>(bc.grid.size());
  for (int g = 0; g + 1 < grid_count; ++g) {
    const glm::vec3* a = &track[static_cast<std::size_t>(g) * stride];
    const glm::vec3* b = a + stride;
    std::size_t low = 1;
    for (std::size_t e = 2; e <= ends; ++e)
      if (a[e].y < a[low].y) low = e;
    if (a[low].y - bc.bounds[bc.grid[g]][0].y > 0.15f * height) continue;  // no end joint near the ground
    const glm::vec3 d = (b[0] - b[low]) - (a[0] - a[low]);       // the body over the foot
    steps.emplace_back(d.x, d.z);
    sum += steps.back();
  }
  if (steps.empty() || 4 * steps.size() < static_cast<std::size_t>(grid_count - 1) || glm::length(sum) <= 0.0f)
    return 0.0f;
  const glm::vec2 u = glm::normalize(sum);
  std::vector<float> speeds;
  for (const glm::vec2& d : steps) speeds.push_back(glm::dot(d, u) * bc.rate);
  std::nth_element(speeds.begin(), speeds.begin() + speeds.size() / 2, speeds.end());
  const float v = speeds[speeds.size() / 2];
  return v >= 0.05f * height ? v : 0.0f;
}

// Closes each part's cuts (PartIndices::Range::caps): the edges its triangles use once that the
// level's triangles use twice (positions welded, so UV seams and primitive borders are not cuts,
// and the mesh's own borders stay open), chained into openings, each closed by a fan from its
// centre wound against the part's triangles there, so that it faces out of the part.
void add_part_caps(const MeshLod& ml, int parts, PartIndices& pi) {
  const std::size_t nv = ml.vertices.size(), prims = ml.primitives.size();
  const std::size_t np = static_cast<std::size_t>(parts);
  // Welded vertex ids: the first of each run of equal bind positions (equal bits, so that a file's
  // NaN cannot break the order), sorted.
  std::vector<std::uint32_t> order(nv), weld(nv);
  std::vector<std::array<std::uint32_t, 3>> bits(nv);
  for (std::uint32_t v = 0; v < nv; ++v) {
    order[v] = v;
    std::memcpy(bits[v].data(), &ml.vertices[v].position, sizeof bits[v]);
  }
  std::sort(order.begin(), order.end(), [&](std::uint32_t a, std::uint32_t b) { return bits[a] < bits[b]; });
  for (std::size_t i = 0; i < nv; ++i)
    weld[order[i]] = i > 0 && bits[order[i]] == bits[order[i - 1]] ? weld[order[i - 1]] : order[i];
  auto edge = [&](std::uint32_t a, std::uint32_t b) {
    a = weld[a], b = weld[b];
    return (std::uint64_t{std::min(a, b)} << 32) | std::max(a, b);
  };
  std::unordered_map<std::uint64_t, int> level_uses, uses;
  for (const Primitive& prim : ml.primitives)
    for (std::uint32_t t = prim.first_index; t + 2 < prim.first_index + prim.index_count; t += 3)
      for (int c = 0; c < 3; ++c) ++level_uses[edge(ml.indices[t + c], ml.indices[t + (c + 1) % 3])];

  struct Cut {
    std::uint32_t a, b;  // as the part's triangle runs along it (level vertex ids)
    std::size_t range;   // the part's range of the primitive that triangle is in
  };
  std::vector<std::vector<std::uint32_t>> caps(pi.ranges.size());
  std::vector<Cut> cut;
  std::unordered_multimap<std::uint32_t, std::size_t> from;
  std::vector<char> chained;
  std::vector<std::size_t> loop;
  for (std::size_t p = 0; p < np; ++p) {
    uses.clear();
    for (std::size_t k = 0; k < prims; ++k) {
      const PartIndices::Range& r = pi.ranges[k * np + p];
      for (std::uint32_t t = r.first; t + 2 < r.first + r.count; t += 3)
        for (int c = 0; c < 3; ++c) ++uses[edge(pi.indices[t + c], pi.indices[t + (c + 1) % 3])];
    }
    cut.clear();
    for (std::size_t k = 0; k < prims; ++k) {
      const PartIndices::Range& r = pi.ranges[k * np + p];
      for (std::uint32_t t = r.first; t + 2 < r.first + r.count; t += 3)
        for (int c = 0; c < 3; ++c) {
          const std::uint32_t a = pi.indices[t + c], b = pi.indices[t + (c + 1) % 3];
          const std::uint64_t e = edge(a, b);
          if (uses[e] == 1 && level_uses[e] == 2) cut.push_back({a, b, k * np + p});
        }
    }
    from.clear();
    for (std::size_t i = 0; i < cut.size(); ++i) from.emplace(weld[cut[i].a], i);
    chained.assign(cut.size(), 0);
    for (std::size_t s = 0; s < cut.size(); ++s) {
      if (chained[s]) continue;
      // One opening: the cut's edges end to end from s, until none goes on.
      loop.clear();
      for (std::size_t e = s;;) {
        chained[e] = 1;
        loop.push_back(e);
        auto [lo, hi] = from.equal_range(weld[cut[e].b]);
        while (lo != hi && chained[lo->second]) ++lo;
        if (lo == hi) break;
        e = lo->second;
      }
      if (loop.size() < 4) continue;  // a lone triangle or a sliver, not an opening
      // The centre.
      Vertex centre;
      centre.position = glm::vec3(0.0f);
      centre.normal = glm::vec3(0.0f);
      glm::vec4 color(0.0f);
      std::vector<std::pair<int, float>> joint_weight;
      for (std::size_t e : loop) {
        const Vertex& v = ml.vertices[cut[e].a];
        centre.position += v.position;
        centre.normal += v.normal;
        color += glm::vec4(v.color);
        for (int j = 0; j < 4; ++j) {
          if (v.weights[j] <= 0.0f) continue;
          auto it = std::find_if(joint_weight.begin(), joint_weight.end(), [&](const auto& jw) { return jw.first == v.joints[j]; });
          if (it == joint_weight.end())
            joint_weight.emplace_back(v.joints[j], v.weights[j]);
          else
            it->second += v.weights[j];
        }
      }
      const float n = static_cast<float>(loop.size());
      centre.position /= n;
      centre.normal /= n;
      centre.color = glm::u8vec4(glm::round(color / n));
      std::sort(joint_weight.begin(), joint_weight.end(), [](const auto& x, const auto& y) { return x.second > y.second || (x.second == y.second && x.first < y.first); });
      float sum = 0.0f;
      for (std::size_t j = 0; j < 4 && j < joint_weight.size(); ++j) sum += joint_weight[j].second;
      centre.joints = glm::u16vec4(0);
      centre.weights = glm::vec4(0.0f);
      for (std::size_t j = 0; j < 4 && j < joint_weight.size(); ++j) {
        centre.joints[static_cast<int>(j)] = static_cast<std::uint16_t>(joint_weight[j].first);
        centre.weights[static_cast<int>(j)] = joint_weight[j].second / sum;
      }
      // The fan, each triangle on corners of its own (b, a, centre), in the primitive of the part's
      // triangle at its edge.
      for (std::size_t e : loop) {
        const Vertex& a = ml.vertices[cut[e].a];
        const Vertex& b = ml.vertices[cut[e].b];
        const std::uint32_t at = static_cast<std::uint32_t>(nv + pi.cap_vertices.size());
        Vertex c = centre;
        c.uv = 0.5f * (a.uv + b.uv);
        pi.cap_vertices.push_back(b);
        pi.cap_vertices.push_back(a);
        pi.cap_vertices.push_back(c);
        caps[cut[e].range].insert(caps[cut[e].range].end(), {at, at + 1, at + 2});
      }
    }
  }
  // Each range's triangles, then its caps.
  std::vector<std::uint32_t> indices;
  for (std::size_t i = 0; i < pi.ranges.size(); ++i) {
    PartIndices::Range& r = pi.ranges[i];
    const std::uint32_t first = static_cast<std::uint32_t>(indices.size());
    indices.insert(indices.end(), pi.indices.begin() + r.first, pi.indices.begin() + r.first + r.count);
    indices.insert(indices.end(), caps[i].begin(), caps[i].end());
    r.first = first;
    r.caps = static_cast<std::uint32_t>(caps[i].size());
  }
  pi.indices = std::move(indices);
}

}  // namespace

void Model::bake(float rate) {
  rate = rate > 0.0f ? rate : 60.0f;
  baked_.clear();
  baked_palette_.clear();
  const std::size_t nn = nodes.size(), np = palette.size();
  std::vector<Transform> locals(nn);
  std::vector<glm::mat4> world(nn), pal(np);
  // The skeleton's root: the palette node with no palette ancestor (first one found).
  const SkeletonFlags skeleton = skeleton_flags(*this);
  int root = palette.empty() ? -1 : palette.front().node;
  while (root >= 0 && nodes[root].parent >= 0 && skeleton.joint[nodes[root].parent]) root = nodes[root].parent;
  glm::vec2 rest_root(0.0f);
  if (root >= 0) {
    sample_clip(*this, -1, 0.0f, locals);
    world_matrices(*this, locals, world);
    rest_root = glm::vec2(world[root][3].x, world[root][3].z);
  }
  // End joints: the feet's candidates for ground_speed.
  std::vector<int> ends;
  for (std::size_t i = 0; i < nn; ++i)
    if (skeleton.joint[i] && !skeleton.parent_of_joint[i]) ends.push_back(static_cast<int>(i));
  // Per clip and grid frame: the skeleton root's place, then each end joint's place (model space).
  std::vector<std::vector<glm::vec3>> tracks;
  const int clip_count = std::max<int>(1, static_cast<int>(clips.size()));
  for (int ci = 0; ci < clip_count; ++ci) {
    const int clip = clips.empty() ? -1 : ci;
    const float dur = clip_duration(clip);
    BakedClip bc;
    bc.rate = rate;
    lay_out_frames(*this, clip, dur, rate, bc);
    bc.first_row = static_cast<std::uint32_t>(baked_palette_.size() / std::max<std::size_t>(1, np * 3));
    tracks.emplace_back();
    for (int f = 0; f < bc.frame_count; ++f) {
      sample_frame(*this, clip, bc, f, locals);
      world_matrices(*this, locals, world);
      palette_matrices(*this, world, pal);
      bc.root_offset.push_back(root >= 0 ? glm::vec2(world[root][3].x, world[root][3].z) - rest_root : glm::vec2(0.0f));
      for (const glm::mat4& m : pal)
        for (int r = 0; r < 3; ++r) baked_palette_.emplace_back(m[0][r], m[1][r], m[2][r], m[3][r]);
      if (!std::binary_search(bc.grid.begin(), bc.grid.end(), f)) continue;  // ground_speed reads the grid
      tracks.back().push_back(root >= 0 ? glm::vec3(world[root][3]) : glm::vec3(0.0f));
      for (int e : ends) tracks.back().push_back(glm::vec3(world[e][3]));
    }
    baked_.push_back(std::move(bc));
  }
  // Section 4.2: bounds of every pose of every clip (finest level), then the radius around their centre.
  const MeshLod& lod = lods.empty() ? MeshLod{} : lods.front();
  auto skin = [&](const Vertex& v, std::size_t frame_row) {
    glm::vec3 p(0.0f);
    for (int k = 0; k < 4; ++k) {
      if (v.weights[k] == 0.0f) continue;
      const glm::vec4* r = &baked_palette_[(frame_row * np + v.joints[k]) * 3];
      glm::vec4 h(v.position, 1.0f);
      p += v.weights[k] * glm::vec3(glm::dot(r[0], h), glm::dot(r[1], h), glm::dot(r[2], h));
    }
    return p;
  };
  glm::vec3 lo(std::numeric_limits<float>::max()), hi(-std::numeric_limits<float>::max());
  glm::vec3 rel_lo = lo, rel_hi = hi;  // relative to the root's horizontal travel
  for (BakedClip& bc : baked_) {
    // Per-frame bounds (for tight impostor quads): measured at up to 120 frames per clip, each
    // frame takes the union of the measured frames around it.
    const int stride = sample_stride(bc.frame_count, 120);
    std::vector<std::array<glm::vec3, 2>> measured;
    for (int f = 0; f < bc.frame_count; f += stride) {
      glm::vec3 flo(std::numeric_limits<float>::max()), fhi(-std::numeric_limits<float>::max());
      for (const Vertex& v : lod.vertices) {
        glm::vec3 p = skin(v, bc.first_row + f);
        flo = glm::min(flo, p);
        fhi = glm::max(fhi, p);
      }
      if (lod.vertices.empty()) flo = fhi = glm::vec3(0.0f);
      measured.push_back({flo, fhi});
      lo = glm::min(lo, flo);
      hi = glm::max(hi, fhi);
      const glm::vec3 ro(bc.root_offset[f].x, 0.0f, bc.root_offset[f].y);
      rel_lo = glm::min(rel_lo, flo - ro);
      rel_hi = glm::max(rel_hi, fhi - ro);
    }
    bc.bounds.resize(bc.frame_count);
    for (int f = 0; f < bc.frame_count; ++f) {
      const std::size_t a = static_cast<std::size_t>(f / stride);
      const std::size_t b = std::min(a + (f % stride ? 1 : 0), measured.size() - 1);
      bc.bounds[f] = {glm::min(measured[a][0], measured[b][0]), glm::max(measured[a][1], measured[b][1])};
    }
  }
  if (lod.vertices.empty()) lo = hi = glm::vec3(0.0f);
  bounds_min = lo;
  bounds_max = hi;
  const float height = hi.y - lo.y;
  for (std::size_t ci = 0; ci < baked_.size() && !ends.empty() && height > 0.0f; ++ci)
    baked_[ci].ground_speed = ground_speed(baked_[ci], tracks[ci], ends.size(), height);
  if (lod.vertices.empty()) rel_lo = rel_hi = glm::vec3(0.0f);
  ta = 0.5f * (rel_lo + rel_hi);
  float r2 = 0.0f;
  for (const BakedClip& bc : baked_)
    for (int f = 0; f < bc.frame_count; f += sample_stride(bc.frame_count, 120))
      for (const Vertex& v : lod.vertices) {
        glm::vec3 d = skin(v, bc.first_row + f) - ta - glm::vec3(bc.root_offset[f].x, 0.0f, bc.root_offset[f].y);
        r2 = std::max(r2, glm::dot(d, d));
      }
  // Frames between the sampled ones can reach a little further.
  radius = std::max(1e-4f, std::sqrt(r2) * 1.02f);
  const glm::vec3 margin(0.02f * radius);
  for (BakedClip& bc : baked_)
    for (auto& b : bc.bounds) b = {b[0] - margin, b[1] + margin};
  bake_posture();
  split_parts({});
}

void Model::set_body_parts(std::span<const int> bones) { split_parts(bones); }

void Model::split_parts(std::span<const int> bones) {
  // A joint starts a part when its subtree holds this share of the skin weight and it turns this
  // much relative to its parent's part (flow test bed, 8 degrees: 2.5 % / 25 degrees gave 7 parts
  // and 21.2 dB, 1.5 % / 12 degrees 12 parts and 22.8 dB).
  constexpr float kPartMass = 0.015f, kPartTurnDeg = 12.0f;
  const int np = static_cast<int>(palette.size());
  parts_.clear();
  part_indices_.clear();
  auto single = [&] {
    parts_.assign(1, BodyPart{});
    parts_[0].mass = 1.0f;
    for (int j = 0; j < np; ++j) parts_[0].joints.push_back(j);
    part_indices_.resize(lods.size());
    for (std::size_t l = 0; l < lods.size(); ++l) {
      part_indices_[l].indices = lods[l].indices;
      for (const Primitive& p : lods[l].primitives) part_indices_[l].ranges.push_back({p.first_index, p.index_count});
    }
    parts_[0].box_min = bounds_min;
    parts_[0].box_max = bounds_max;
    parts_[0].centre = ta;
    parts_[0].radius = radius;
  };
  if (np == 0 || lods.empty() || baked_.empty()) return single();
  // The skin's joint tree (palette entries), parents first.
  std::vector<int> pal_of_node(nodes.size(), -1);
  for (int j = np - 1; j >= 0; --j) pal_of_node[palette[j].node] = j;
  std::vector<int> parent(np, -1), order(np);
  for (int j = 0; j < np; ++j) {
    for (int a = nodes[palette[j].node].parent; a >= 0 && parent[j] < 0; a = nodes[a].parent) parent[j] = pal_of_node[a];
    order[j] = j;
  }
  std::stable_sort(order.begin(), order.end(), [&](int a, int b) { return palette[a].node < palette[b].node; });
  const MeshLod& fine = lods.front();
  std::vector<float> mass(np, 0.0f), subtree(np, 0.0f);
  float total = 0.0f;
  for (const Vertex& v : fine.vertices)
    for (int k = 0; k < 4; ++k)
      if (v.weights[k] > 0.0f && v.joints[k] < np) {
        mass[v.joints[k]] += v.weights[k];
        total += v.weights[k];
      }
  if (!(total > 0.0f)) return single();
  for (int j = 0; j < np; ++j) subtree[j] = mass[j];
  for (int k = np - 1; k >= 0; --k)
    if (parent[order[k]] >= 0) subtree[parent[order[k]]] += subtree[order[k]];
  // Sampled frames (rows of the baked palette) of every clip.
  std::vector<std::size_t> rows;
  for (const BakedClip& bc : baked_)
    for (int f = 0; f < bc.frame_count; f += sample_stride(bc.frame_count, 60)) rows.push_back(bc.first_row + f);
  auto pal = [&](std::size_t row, int j) {
    const glm::vec4* r = &baked_palette_[(row * np + j) * 3];
    glm::mat4 m(1.0f);
    for (int c = 0; c < 4; ++c)
      for (int k = 0; k < 3; ++k) m[c][k] = r[k][c];
    return m;
  };
  auto rot = [](const glm::mat4& m) {
    glm::mat3 r(m);
    for (int c = 0; c < 3; ++c) r[c] = glm::length(r[c]) > 1e-12f ? glm::normalize(r[c]) : r[c];
    return r;
  };
  // Part of each joint; a part's bone is the joint that starts it.
  std::vector<int> part_of(np, -1), bone;
  for (int j : order) {
    bool starts = parent[j] < 0;
    if (!starts && !bones.empty()) {
      starts = std::find(bones.begin(), bones.end(), j) != bones.end();
    } else if (!starts && subtree[j] >= kPartMass * total) {
      // How far j turns relative to its parent's part over the clips (angle from the first frame).
      const int b = bone[part_of[parent[j]]];
      glm::mat3 first(1.0f);
      float cos_min = 1.0f;
      for (std::size_t k = 0; k < rows.size(); ++k) {
        const glm::mat3 r = rot(glm::inverse(pal(rows[k], b)) * pal(rows[k], j));
        if (k == 0) first = r;
        const float t = glm::dot(first[0], r[0]) + glm::dot(first[1], r[1]) + glm::dot(first[2], r[2]);
        cos_min = std::min(cos_min, 0.5f * (t - 1.0f));
      }
      starts = cos_min < std::cos(glm::radians(kPartTurnDeg));
    }
    if (starts) {
      part_of[j] = static_cast<int>(bone.size());
      bone.push_back(j);
    } else {
      part_of[j] = part_of[parent[j]];
    }
  }
  // Parts with almost no skin of their own join their parent's part; at most 16 parts.
  int parts = static_cast<int>(bone.size());
  for (;;) {
    std::vector<float> own(parts, 0.0f);
    for (int j = 0; j < np; ++j) own[part_of[j]] += mass[j];
    int worst = -1;
    for (int p = 1; p < parts; ++p)
      if (parent[bone[p]] >= 0 && (own[p] < 0.005f * total || parts > kMaxBodyParts) && (worst < 0 || own[p] < own[worst])) worst = p;
    if (worst < 0) {
      parts_.resize(parts);
      for (int p = 0; p < parts; ++p) parts_[p].mass = own[p] / total;
      break;
    }
    const int into = part_of[parent[bone[worst]]];
    for (int& q : part_of) q = q == worst ? into : q > worst ? q - 1 : q;
    bone.erase(bone.begin() + worst);
    --parts;
  }
  if (parts < 2) return single();
  for (int p = 0; p < parts; ++p) parts_[p].bone = bone[p];
  for (int j = 0; j < np; ++j) parts_[part_of[j]].joints.push_back(j);

  // Triangles: the part with most weight, plus every part weighing >= 0.7 on one of its vertices.
  // (0.7: 24.0 dB at 8 degrees; 0.3: 22.8, the overlapping flaps at the hips show; none: 23.9.)
  constexpr float kOverlap = 0.7f;
  std::vector<float> vw;
  part_indices_.resize(lods.size());
  std::vector<std::vector<char>> used(parts);  // finest level: vertices of each part's triangles
  for (std::size_t l = 0; l < lods.size(); ++l) {
    const MeshLod& ml = lods[l];
    const std::size_t nv = ml.vertices.size();
    vw.assign(nv * parts, 0.0f);
    for (std::size_t v = 0; v < nv; ++v)
      for (int k = 0; k < 4; ++k)
        if (ml.vertices[v].weights[k] > 0.0f && ml.vertices[v].joints[k] < np)
          vw[v * parts + part_of[ml.vertices[v].joints[k]]] += ml.vertices[v].weights[k];
    if (l == 0)
      for (auto& u : used) u.assign(nv, 0);
    PartIndices& pi = part_indices_[l];
    for (const Primitive& prim : ml.primitives)
      for (int p = 0; p < parts; ++p) {
        PartIndices::Range r{static_cast<std::uint32_t>(pi.indices.size()), 0};
        for (std::uint32_t t = prim.first_index; t + 2 < prim.first_index + prim.index_count; t += 3) {
          const std::uint32_t* tri = &ml.indices[t];
          int best = 0;
          float best_w = -1.0f, wp = 0.0f, peak = 0.0f;
          for (int q = 0; q < parts; ++q) {
            const float w = vw[tri[0] * parts + q] + vw[tri[1] * parts + q] + vw[tri[2] * parts + q];
            if (w > best_w) best_w = w, best = q;
          }
          for (int c = 0; c < 3; ++c) {
            wp += vw[tri[c] * parts + p];
            peak = std::max(peak, vw[tri[c] * parts + p]);
          }
          (void)wp;
          if (best != p && peak < kOverlap) continue;
          pi.indices.insert(pi.indices.end(), tri, tri + 3);
          r.count += 3;
          if (l == 0)
            for (int c = 0; c < 3; ++c) used[p][tri[c]] = 1;
        }
        pi.ranges.push_back(r);
      }
    add_part_caps(ml, parts, pi);
  }
  // Bounds of each part in its bone's palette space, over the sampled frames.
  auto skin_at = [&](const Vertex& v, std::size_t row) {
    glm::vec3 p(0.0f);
    for (int k = 0; k < 4; ++k) {
      if (v.weights[k] == 0.0f) continue;
      p += v.weights[k] * glm::vec3(pal(row, v.joints[k]) * glm::vec4(v.position, 1.0f));
    }
    return p;
  };
  for (int p = 0; p < parts; ++p) {
    BodyPart& bp = parts_[p];
    glm::vec3 lo(std::numeric_limits<float>::max()), hi(-std::numeric_limits<float>::max());
    for (int pass = 0; pass < 2; ++pass) {
      float r2 = 0.0f;
      for (std::size_t row : rows) {
        const glm::mat4 inv = glm::inverse(pal(row, bp.bone));
        for (std::size_t v = 0; v < fine.vertices.size(); ++v) {
          if (!used[p][v]) continue;
          const glm::vec3 q(inv * glm::vec4(skin_at(fine.vertices[v], row), 1.0f));
          if (pass == 0) {
            lo = glm::min(lo, q);
            hi = glm::max(hi, q);
          } else {
            r2 = std::max(r2, glm::dot(q - bp.centre, q - bp.centre));
          }
        }
      }
      if (pass == 0) {
        if (lo.x > hi.x) lo = hi = glm::vec3(0.0f);
        bp.centre = 0.5f * (lo + hi);
      } else {
        bp.radius = std::max(1e-4f, std::sqrt(r2) * 1.02f);
      }
    }
    bp.box_min = lo - glm::vec3(0.02f * bp.radius);
    bp.box_max = hi + glm::vec3(0.02f * bp.radius);
    // Principal axes of the same points (the first frame sampled): covariance, then power
    // rotations (below) for the eigenvalues and axes.
    if (!rows.empty()) {
      const glm::mat4 inv = glm::inverse(pal(rows.front(), bp.bone));
      glm::dvec3 mean(0.0);
      double count = 0;
      std::vector<glm::dvec3> pts;
      for (std::size_t v = 0; v < fine.vertices.size(); ++v) {
        if (!used[p][v]) continue;
        pts.emplace_back(glm::vec3(inv * glm::vec4(skin_at(fine.vertices[v], rows.front()), 1.0f)));
        mean += pts.back();
        count += 1;
      }
      if (count >= 3) {
        mean /= count;
        glm::dmat3 cov(0.0);
        for (const auto& q : pts) cov += glm::outerProduct(q - mean, q - mean);
        cov /= count;
        // Jacobi rotations: cov = V diag(e) V^T, columns of V the principal axes.
        glm::dmat3 a = cov, v(1.0);
        for (int sweep = 0; sweep < 16; ++sweep) {
          const double off = a[1][0] * a[1][0] + a[2][0] * a[2][0] + a[2][1] * a[2][1];
          if (off < 1e-30) break;
          for (int pi = 0; pi < 2; ++pi)
            for (int qi = pi + 1; qi < 3; ++qi) {
              if (std::abs(a[qi][pi]) < 1e-300) continue;
              const double theta = 0.5 * std::atan2(2.0 * a[qi][pi], a[qi][qi] - a[pi][pi]);
              const double c = std::cos(theta), sn = std::sin(theta);
              glm::dmat3 r(1.0);  // rotation in the (pi, qi) plane
              r[pi][pi] = c;
              r[qi][qi] = c;
              r[qi][pi] = sn;   // column qi, row pi
              r[pi][qi] = -sn;  // column pi, row qi
              a = glm::transpose(r) * a * r;
              v = v * r;
            }
        }
        std::array<int, 3> by_size{0, 1, 2};
        std::sort(by_size.begin(), by_size.end(), [&](int x, int y) { return a[x][x] > a[y][y]; });
        const double l1 = std::max(a[by_size[0]][by_size[0]], 0.0), l2 = std::max(a[by_size[1]][by_size[1]], 1e-12),
                     l3 = std::max(a[by_size[2]][by_size[2]], 1e-12);
        bp.axis = glm::vec3(glm::normalize(v[by_size[0]]));
        bp.elongation = static_cast<float>(std::sqrt(std::max(l1, l2) / l2));
        bp.flatness = static_cast<float>(std::sqrt(std::max(l2, l3) / l3));
      }
    }
  }
}

void Model::bake_posture() {
  const std::size_t nn = nodes.size();
  std::vector<Transform> locals(nn);
  std::vector<glm::mat4> world(nn);
  if (posture_pairs_.empty()) {
    // Section 5.1, for any skeleton: candidate points are the skeleton's end effectors (leaf joints)
    // and points beyond them along their last bone; the pairs are the widest-spanning ones whose
    // distance actually changes in the clips, each point used at most twice.
    const SkeletonFlags skeleton = skeleton_flags(*this);
    const std::vector<bool>&in_skeleton = skeleton.joint, &has_child = skeleton.parent_of_joint;
    sample_clip(*this, -1, 0.0f, locals);
    world_matrices(*this, locals, world);
    std::vector<PosturePoint> points;
    int leaves = 0;
    for (std::size_t i = 0; i < nn; ++i) {
      if (!in_skeleton[i] || has_child[i]) continue;
      ++leaves;
      // A point beyond the leaf along its last bone (so a 2-joint chain bends measurably), or
      // the leaf itself.
      PosturePoint pt{static_cast<int>(i), glm::vec3(0.0f)};
      int p = nodes[i].parent;
      if (p >= 0) {
        glm::vec3 a(world[p][3]), b(world[i][3]);
        if (glm::length(b - a) > 1e-6f) pt.offset = glm::vec3(glm::inverse(world[i]) * glm::vec4(b + 0.5f * (b - a), 1.0f));
      }
      points.push_back(pt);
    }
    if (leaves < 3)
      for (std::size_t i = 0; i < nn; ++i)
        if (in_skeleton[i] && has_child[i]) points.push_back(PosturePoint{static_cast<int>(i), glm::vec3(0.0f)});
    if (points.size() > 64) points.resize(64);  // bounded cost on huge skeletons
    const std::size_t n = points.size();
    struct Cand { int a, b; float rest, lo, hi; };
    std::vector<Cand> cands;
    for (std::size_t a = 0; a < n; ++a)
      for (std::size_t b = a + 1; b < n; ++b) {
        float d = glm::distance(point_position(points[a], world), point_position(points[b], world));
        cands.push_back(Cand{static_cast<int>(a), static_cast<int>(b), d, d, d});
      }
    std::vector<glm::vec3> pos(n);
    for (std::size_t ci = 0; ci < clips.size(); ++ci) {
      const BakedClip& bc = baked_[ci];
      for (int f = 0; f < bc.frame_count; f += sample_stride(bc.frame_count, 60)) {
        sample_frame(*this, static_cast<int>(ci), bc, f, locals);
        world_matrices(*this, locals, world);
        for (std::size_t k = 0; k < n; ++k) pos[k] = point_position(points[k], world);
        for (Cand& c : cands) {
          float d = glm::distance(pos[c.a], pos[c.b]);
          c.lo = std::min(c.lo, d);
          c.hi = std::max(c.hi, d);
        }
      }
    }
    auto varies = [](const Cand& c) { return c.hi - c.lo > 1e-3f * std::max(c.hi, 1e-6f); };
    std::stable_sort(cands.begin(), cands.end(), [&](const Cand& x, const Cand& y) {
      if (varies(x) != varies(y)) return varies(x);
      return x.rest > y.rest;
    });
    // Points closer than 15 % of the radius in the rest pose are one limb end (the fingertips of a
    // hand). No two pairs join the same two limb ends, and in the first pass no limb end serves
    // more than twice: feet-head, hand-hand, hand-foot for a human.
    sample_clip(*this, -1, 0.0f, locals);
    world_matrices(*this, locals, world);
    std::vector<int> end_of(n);
    for (std::size_t a = 0; a < n; ++a) {
      end_of[a] = static_cast<int>(a);
      for (std::size_t b = 0; b < a; ++b)
        if (glm::distance(point_position(points[a], world), point_position(points[b], world)) < 0.15f * radius) {
          end_of[a] = end_of[b];
          break;
        }
    }
    std::vector<int> uses(n, 0);
    std::vector<std::pair<int, int>> joined;
    for (int pass = 0; pass < 3 && posture_pairs_.size() < kPosturePairs; ++pass)
      for (const Cand& c : cands) {
        if (posture_pairs_.size() >= kPosturePairs) break;
        const int la = end_of[c.a], lb = end_of[c.b];
        if (pass == 0 && (uses[la] >= 2 || uses[lb] >= 2)) continue;
        const auto key = std::minmax(la, lb);
        if (pass < 2 && std::find(joined.begin(), joined.end(), std::pair<int, int>(key.first, key.second)) != joined.end())
          continue;
        bool dup = false;
        for (const auto& pp : posture_pairs_)
          dup |= pp.a.node == points[c.a].node && pp.a.offset == points[c.a].offset && pp.b.node == points[c.b].node &&
                 pp.b.offset == points[c.b].offset;
        if (dup) continue;
        posture_pairs_.push_back(PosturePair{points[c.a], points[c.b]});
        joined.emplace_back(key.first, key.second);
        ++uses[la];
        ++uses[lb];
      }
    if (posture_pairs_.empty()) posture_pairs_.push_back(PosturePair{});
    while (posture_pairs_.size() < kPosturePairs) posture_pairs_.push_back(posture_pairs_.back());
  }
  for (std::size_t ci = 0; ci < baked_.size(); ++ci) {
    BakedClip& bc = baked_[ci];
    const int clip = clips.empty() ? -1 : static_cast<int>(ci);
    bc.posture.resize(bc.frame_count);
    for (int f = 0; f < bc.frame_count; ++f) {
      sample_frame(*this, clip, bc, f, locals);
      world_matrices(*this, locals, world);
      for (int k = 0; k < kPosturePairs; ++k) {
        glm::vec3 d = point_position(posture_pairs_[k].a, world) - point_position(posture_pairs_[k].b, world);
        bc.posture[f][k] = glm::dot(d, d);
      }
    }
  }
}

}  // namespace bb::runtime
