#include <algorithm>
#include <cmath>

#include "bb/decimate/decimate.h"
#include "triangle_grid.h"

namespace bb::decimate {

namespace {

using detail::TriangleGrid;

// Distances from the vertices and face centres of mesh a to mesh b: max and sum, count.
void one_sided(const std::vector<glm::vec3>& pa, const std::vector<uint32_t>& ia, const TriangleGrid& gb,
               double* max_d, double* sum, size_t* n) {
  for (const auto& v : pa) {
    double d = gb.distance(v);
    *max_d = std::max(*max_d, d);
    *sum += d;
    ++*n;
  }
  for (size_t t = 0; t + 2 < ia.size(); t += 3) {
    glm::vec3 c = (pa[ia[t]] + pa[ia[t + 1]] + pa[ia[t + 2]]) / 3.0f;
    double d = gb.distance(c);
    *max_d = std::max(*max_d, d);
    *sum += d;
    ++*n;
  }
}

}  // namespace

Distance mesh_distance(const std::vector<glm::vec3>& pa, const std::vector<uint32_t>& ia,
                       const std::vector<glm::vec3>& pb, const std::vector<uint32_t>& ib) {
  Distance out;
  if (ia.empty() || ib.empty()) return out;
  TriangleGrid ga(pa, ia), gb(pb, ib);
  double max_ab = 0, sum_ab = 0, max_ba = 0, sum_ba = 0;
  size_t n_ab = 0, n_ba = 0;
  one_sided(pa, ia, gb, &max_ab, &sum_ab, &n_ab);
  one_sided(pb, ib, ga, &max_ba, &sum_ba, &n_ba);
  out.hausdorff_m = std::max(max_ab, max_ba);
  out.mean_m = 0.5 * (sum_ab / std::max<size_t>(1, n_ab) + sum_ba / std::max<size_t>(1, n_ba));
  return out;
}

}  // namespace bb::decimate
