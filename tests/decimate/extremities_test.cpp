// Decimated extremities and textured proxies on the default body's real LOD chain.
#include <cstdlib>
#include <map>
#include <set>

#include <gtest/gtest.h>

#include "bb/decimate/extremities.h"
#include "bb/mesher/mesh_check.h"
#include "bb/mesher/mesher.h"
#include "bb/modeler/body.h"

using namespace bb;

namespace {

struct Chain {
  std::vector<mesher::Lod> lods;       // the default chain
  mesher::SkinnedMesh mid_full;        // LOD 1 density with full-resolution extremities
};

const Chain& chain() {
  static Chain c = [] {
    Chain out;
    mesher::MesherOptions o;
    o.error_samples = 0;
    o.check_topology = false;
    auto lods = mesher::build_lods(modeler::default_body(), o);
    EXPECT_TRUE(lods) << lods.error().message();
    if (lods) out.lods = std::move(*lods);
    mesher::MesherOptions o1 = o;
    o1.lods = {mesher::default_lod_chain()[1]};
    o1.lods[0].vdb_extremities = true;
    auto mid = mesher::build_lods(modeler::default_body(), o1);
    EXPECT_TRUE(mid) << mid.error().message();
    if (mid) out.mid_full = (*mid)[0].mesh;
    return out;
  }();
  return c;
}

size_t extremity_triangles(const mesher::SkinnedMesh& m) {
  size_t n = 0;
  for (size_t t = 0; t < m.indices.size(); t += 3) {
    uint8_t p = m.part[m.indices[t]];
    n += p != 0 && m.part[m.indices[t + 1]] == p && m.part[m.indices[t + 2]] == p;
  }
  return n;
}

}  // namespace

TEST(Extremities, DecimatedToBudgetStayClosedWithSeamsInPlace) {
  const auto& m = chain().mid_full;
  ASSERT_FALSE(m.positions.empty());
  size_t before = extremity_triangles(m);
  ASSERT_GT(before, 10000u);
  decimate::Report rep;
  auto r = decimate::decimate_extremities(m, 2000, &rep);
  ASSERT_TRUE(r) << r.error().message();
  size_t after = extremity_triangles(*r);
  EXPECT_LE(after, 2100u);
  EXPECT_GE(after, 1500u);
  // Every seam and body vertex survives at its exact position.
  std::set<std::tuple<float, float, float>> kept;
  for (auto p : r->positions) kept.insert({p.x, p.y, p.z});
  for (size_t i = 0; i < m.positions.size(); ++i)
    if (m.part[i] == 0 || m.seam[i]) {
      ASSERT_TRUE(kept.count({m.positions[i].x, m.positions[i].y, m.positions[i].z})) << i;
    }
  // Still one closed, oriented 2-manifold (no crack at the seams).
  auto before_check = mesher::check_mesh(m.positions, m.indices, false);
  auto check = mesher::check_mesh(r->positions, r->indices, false);
  EXPECT_EQ(check.closed, before_check.closed);
  EXPECT_TRUE(check.closed);
  EXPECT_TRUE(check.manifold);
  EXPECT_TRUE(check.oriented);
  EXPECT_EQ(check.connected_components, 1u);
  EXPECT_GT(rep.hausdorff_m, 0.0);
  EXPECT_LT(rep.hausdorff_m, 0.01);  // under 1 cm for hands, head and feet at ~2,000 triangles
  // Weights of every survivor still sum to one.
  for (const auto& w : r->weights) EXPECT_NEAR(w.x + w.y + w.z + w.w, 1.0f, 1e-5f);
}

TEST(Extremities, ProxiesAreTexturedFromTheDetail) {
  const auto& c = chain();
  ASSERT_GE(c.lods.size(), 2u);
  const auto& coarse = c.lods.back().mesh;
  auto p = decimate::bake_proxies(coarse, c.lods.front().mesh);
  ASSERT_TRUE(p) << p.error().message();
  EXPECT_EQ(p->mesh.triangle_count(), coarse.triangle_count());  // proxies add no triangles
  EXPECT_GT(p->proxy_triangles, 20u);
  ASSERT_EQ(p->mesh.uvs.size(), p->mesh.positions.size());
  for (auto uv : p->mesh.uvs) {
    EXPECT_GE(uv.x, 0.0f);
    EXPECT_LE(uv.x, 1.0f);
    EXPECT_GE(uv.y, 0.0f);
    EXPECT_LE(uv.y, 1.0f);
  }
  // The texture varies where the detail does: the texels are not all the skin colour.
  std::map<uint32_t, int> colours;
  for (size_t i = 0; i < p->rgba.size(); i += 4)
    ++colours[p->rgba[i] << 16 | p->rgba[i + 1] << 8 | p->rgba[i + 2]];
  EXPECT_GT(colours.size(), 50u);
  // Welding by position gives back the closed coarse surface.
  auto check = mesher::check_mesh(coarse.positions, coarse.indices, false);
  EXPECT_TRUE(check.closed);
  if (const char* dir = std::getenv("BB_TEST_OUTPUT")) {
    FILE* f = std::fopen((std::string(dir) + "/proxy_texture.rgba").c_str(), "wb");
    if (f) {
      std::fwrite(p->rgba.data(), 1, p->rgba.size(), f);
      std::fclose(f);
    }
  }
}
