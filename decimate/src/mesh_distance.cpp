#include <algorithm>
#include <cmath>
#include <memory>
#include <numeric>

#include "bb/decimate/decimate.h"
#include "triangle_grid.h"

namespace bb::decimate {

namespace {

using runtime::detail::TriangleGrid;
using runtime::detail::closest_on_triangle;

// Distances from the vertices and face centres of mesh a to mesh b: max and sum, count. Each
// query tries the previous query's nearest triangle first (neighbouring samples mostly share it),
// which bounds the grid search; the result is the same nearest distance.
void one_sided(const std::vector<glm::vec3>& pa, const std::vector<uint32_t>& ia, const TriangleGrid& gb,
               double* max_d, double* sum, size_t* n) {
  glm::vec3 cp;
  uint32_t last_t = UINT32_MAX;
  auto take = [&](const glm::vec3& v) {
    float d = gb.closest(v, &cp, &last_t, 1e15f, last_t);
    *max_d = std::max(*max_d, static_cast<double>(d));
    *sum += d;
    ++*n;
  };
  for (const auto& v : pa) take(v);
  for (size_t t = 0; t + 2 < ia.size(); t += 3) take((pa[ia[t]] + pa[ia[t + 1]] + pa[ia[t + 2]]) / 3.0f);
}

}  // namespace

Distance mesh_distance(const std::vector<glm::vec3>& pa, const std::vector<uint32_t>& ia,
                       const std::vector<glm::vec3>& pb, const std::vector<uint32_t>& ib) {
  Distance out;
  if (ia.empty() || ib.empty()) return out;
  // The coarser mesh answers most queries (the finer one's samples): finer cells there skip more
  // triangles per query; the finer mesh keeps cells of two mean edges (fewer cells to build).
  const bool a_coarser = ia.size() < ib.size();
  TriangleGrid ga(pa, ia, a_coarser ? 0.5f : 2.0f), gb(pb, ib, a_coarser ? 2.0f : 0.5f);
  double max_ab = 0, sum_ab = 0, max_ba = 0, sum_ba = 0;
  size_t n_ab = 0, n_ba = 0;
  one_sided(pa, ia, gb, &max_ab, &sum_ab, &n_ab);
  one_sided(pb, ib, ga, &max_ba, &sum_ba, &n_ba);
  out.hausdorff_m = std::max(max_ab, max_ba);
  out.mean_m = 0.5 * (sum_ab / std::max<size_t>(1, n_ab) + sum_ba / std::max<size_t>(1, n_ba));
  return out;
}

constexpr size_t kCluster = 16;  // samples per cluster of ReferenceDistance

struct ReferenceDistance::Impl {
  std::vector<glm::vec3> pa;
  std::vector<uint32_t> ia;
  std::vector<glm::vec3> samples;  // vertices, then face centres (mesh_distance's order)
  std::unique_ptr<TriangleGrid> grid;
  std::vector<uint32_t> hot;       // samples farthest in the last complete measurement
  std::vector<uint32_t> order;     // samples in Morton order (neighbours share nearest triangles)
  struct Cluster {
    glm::vec3 centre;
    float radius;
  };
  std::vector<Cluster> clusters;   // kCluster consecutive samples of `order` each
};

ReferenceDistance::ReferenceDistance(const std::vector<glm::vec3>& positions, const std::vector<uint32_t>& indices)
    : impl_(new Impl) {
  impl_->pa = positions;
  impl_->ia = indices;
  impl_->samples = positions;
  for (size_t t = 0; t + 2 < indices.size(); t += 3)
    impl_->samples.push_back((positions[indices[t]] + positions[indices[t + 1]] + positions[indices[t + 2]]) / 3.0f);
  impl_->grid = std::make_unique<TriangleGrid>(impl_->pa, impl_->ia, 2.0f);
  // Morton order over a 1024^3 lattice of the samples' bounds.
  const auto& sp = impl_->samples;
  glm::vec3 lo(1e30f), hi(-1e30f);
  for (const auto& p : sp) {
    lo = glm::min(lo, p);
    hi = glm::max(hi, p);
  }
  const glm::vec3 scale = 1023.0f / glm::max(hi - lo, glm::vec3(1e-9f));
  auto spread = [](uint64_t x) {  // 10 bits -> every third of 30
    x &= 0x3ff;
    x = (x | (x << 16)) & 0x30000ff;
    x = (x | (x << 8)) & 0x300f00f;
    x = (x | (x << 4)) & 0x30c30c3;
    x = (x | (x << 2)) & 0x9249249;
    return x;
  };
  std::vector<std::pair<uint64_t, uint32_t>> keys(sp.size());
  for (size_t i = 0; i < sp.size(); ++i) {
    glm::vec3 c = (sp[i] - lo) * scale;
    keys[i] = {spread(uint64_t(c.x)) | (spread(uint64_t(c.y)) << 1) | (spread(uint64_t(c.z)) << 2), uint32_t(i)};
  }
  std::sort(keys.begin(), keys.end());
  impl_->order.resize(sp.size());
  for (size_t i = 0; i < sp.size(); ++i) impl_->order[i] = keys[i].second;
  for (size_t k = 0; k < sp.size(); k += kCluster) {
    const size_t end = std::min(sp.size(), k + kCluster);
    glm::vec3 lo_c(1e30f), hi_c(-1e30f);
    for (size_t j = k; j < end; ++j) {
      lo_c = glm::min(lo_c, sp[impl_->order[j]]);
      hi_c = glm::max(hi_c, sp[impl_->order[j]]);
    }
    Impl::Cluster c{0.5f * (lo_c + hi_c), 0.0f};
    for (size_t j = k; j < end; ++j) c.radius = std::max(c.radius, glm::distance(c.centre, sp[impl_->order[j]]));
    c.radius = c.radius * 1.0001f + 1e-7f;  // rounding
    impl_->clusters.push_back(c);
  }
}

ReferenceDistance::~ReferenceDistance() { delete impl_; }

ReferenceDistance::Measured ReferenceDistance::measure(const std::vector<glm::vec3>& pb,
                                                       const std::vector<uint32_t>& ib, double give_up_above,
                                                       bool with_mean) {
  Measured out;
  Impl& r = *impl_;
  if (r.ia.empty() || ib.empty()) {
    out.complete = true;
    return out;
  }
  // Candidate -> reference (few samples, a fine grid built once).
  double max_ba = 0, sum_ba = 0;
  size_t n_ba = 0;
  one_sided(pb, ib, *r.grid, &max_ba, &sum_ba, &n_ba);
  if (max_ba > give_up_above) {
    out.distance.hausdorff_m = max_ba;
    return out;
  }
  // Reference -> candidate: the hot samples first, then all of them in order.
  const bool coarser = ib.size() < r.ia.size();
  TriangleGrid gb(pb, ib, coarser ? 0.5f : 2.0f);
  glm::vec3 cp;
  uint32_t last_t = UINT32_MAX;
  double max_ab = 0;
  for (uint32_t i : r.hot) {
    float d = gb.closest(r.samples[i], &cp, &last_t, 1e15f, last_t);
    max_ab = std::max(max_ab, static_cast<double>(d));
    if (d > give_up_above) {
      out.distance.hausdorff_m = d;
      return out;
    }
  }
  std::vector<float> dist(r.samples.size());
  double sum_ab = 0;
  last_t = UINT32_MAX;
  for (size_t k = 0; k < r.samples.size(); ++k) {
    if (!with_mean && k % kCluster == 0 && last_t != UINT32_MAX) {
      // A whole cluster of Morton-consecutive samples within the largest distance so far of the
      // last nearest triangle cannot raise the maximum.
      const Impl::Cluster& cl = r.clusters[k / kCluster];
      float upper = glm::distance(cl.centre, closest_on_triangle(cl.centre, pb[ib[3 * last_t]], pb[ib[3 * last_t + 1]],
                                                                 pb[ib[3 * last_t + 2]])) + cl.radius;
      if (upper <= std::max(max_ab, max_ba)) {
        const size_t end = std::min(r.samples.size(), k + kCluster);
        for (size_t j = k; j < end; ++j) dist[r.order[j]] = upper;  // an upper bound (hot order only)
        k = end - 1;
        continue;
      }
    }
    // With the mean: mesh_distance's order (the same sum); without: Morton order.
    const size_t i = with_mean ? k : r.order[k];
    const glm::vec3& q = r.samples[i];
    if (!with_mean && last_t != UINT32_MAX) {
      // Nearer than the largest distance so far to some triangle: cannot raise the maximum.
      float upper = glm::distance(q, closest_on_triangle(q, pb[ib[3 * last_t]], pb[ib[3 * last_t + 1]], pb[ib[3 * last_t + 2]]));
      if (upper <= std::max(max_ab, max_ba)) {
        dist[i] = upper;  // an upper bound; only the order of the hot samples depends on it
        continue;
      }
    }
    // Without the mean only a distance above the largest so far matters: the search may stop at
    // any triangle nearer than that (and searches fully when there is none).
    const float upper = with_mean ? 1e15f : static_cast<float>(std::max(max_ab, max_ba));
    float d = gb.closest(q, &cp, &last_t, upper > 0 ? upper : 1e15f, last_t);
    if (d > give_up_above) {
      out.distance.hausdorff_m = d;
      return out;
    }
    dist[i] = d;
    max_ab = std::max(max_ab, static_cast<double>(d));
    sum_ab += d;
  }
  out.complete = true;
  out.distance.hausdorff_m = std::max(max_ab, max_ba);
  if (with_mean)
    out.distance.mean_m = 0.5 * (sum_ab / static_cast<double>(r.samples.size()) + sum_ba / std::max<size_t>(1, n_ba));
  // The farthest samples become the hot ones for the next candidate.
  const size_t kHot = std::min<size_t>(64, dist.size());
  std::vector<uint32_t> order(dist.size());
  std::iota(order.begin(), order.end(), 0u);
  std::partial_sort(order.begin(), order.begin() + kHot, order.end(),
                    [&](uint32_t a, uint32_t b) { return dist[a] > dist[b]; });
  r.hot.assign(order.begin(), order.begin() + kHot);
  return out;
}

}  // namespace bb::decimate
