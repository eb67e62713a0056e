// Image tests under EGL (llvmpipe without a GPU): geometry and impostor renderings of the same
// frame must agree (PSNR over covered pixels), and the crowd path must draw what the plan says.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdlib>
#include <cstdio>
#include <filesystem>
#include <map>
#include <memory>
#include <string>

#include <gtest/gtest.h>

#include "bb/runtime/headless.h"
#include "bb/runtime/portrait.h"
#include "bb/runtime/renderer.h"
#include "gl.h"  // runtime/src: the GL state a game leaves on
#include "gl_context.h"
#include "tube_model.h"

namespace bb::runtime {
namespace {

namespace fs = std::filesystem;

// `m` = the shared CesiumMan (a Result<Model>, loaded from `path`), or the test skips where
// ../shared/data is absent.
#define LOAD_CESIUM_MAN(m)                                                         \
  const std::string path = std::string(BB_SHARED_DATA_DIR) + "/gltf/CesiumMan.glb"; \
  if (!fs::exists(path)) GTEST_SKIP() << "shared data absent: " << path;          \
  auto m = load_model(path);                                                      \
  ASSERT_TRUE(m.ok()) << m.error().message()

// PSNR in dB over the pixels covered (alpha > 0) in either image; RGB compared with alpha
// premultiplied (background black). Returns 99 when identical.
double covered_psnr(const Image& a, const Image& b, int* covered) {
  double se = 0;
  long n = 0;
  for (std::size_t i = 0; i < a.rgba.size(); i += 4) {
    if (a.rgba[i + 3] == 0 && b.rgba[i + 3] == 0) continue;
    ++n;
    for (int k = 0; k < 3; ++k) {
      double x = a.rgba[i + k] * (a.rgba[i + 3] / 255.0), y = b.rgba[i + k] * (b.rgba[i + 3] / 255.0);
      se += (x - y) * (x - y);
    }
  }
  *covered = static_cast<int>(n);
  if (n == 0 || se == 0) return 99.0;
  double mse = se / (3.0 * n);
  return 10.0 * std::log10(255.0 * 255.0 / mse);
}

void save_ppm_pair(const std::string& path, const Image& a, const Image& b) {
  // Side by side for a person to look at (PPM keeps the test free of PNG code).
  FILE* f = std::fopen(path.c_str(), "wb");
  if (!f) return;
  std::fprintf(f, "P6\n%d %d\n255\n", a.width * 2, a.height);
  for (int y = 0; y < a.height; ++y)
    for (int half = 0; half < 2; ++half)
      for (int x = 0; x < a.width; ++x) {
        const Image& im = half ? b : a;
        const std::uint8_t* p = &im.rgba[(static_cast<std::size_t>(y) * im.width + x) * 4];
        unsigned char c[3];
        for (int k = 0; k < 3; ++k) c[k] = static_cast<unsigned char>((p[k] * p[3] + (255 - p[3]) * 60) / 255);
        std::fwrite(c, 1, 3, f);
      }
  std::fclose(f);
}

class PortraitPsnr : public ::testing::TestWithParam<const char*> {};

// A geometry portrait 256 pixels square of a walking character from `view`: azimuth and elevation
// in degrees, time in seconds.
PortraitOptions walking_view(const std::array<float, 3>& view) {
  PortraitOptions o;
  o.azimuth_deg = view[0];
  o.elevation_deg = view[1];
  o.time = view[2];
  o.width = o.height = 256;
  o.mode = RenderMode::kGeometry;
  return o;
}

// From the front at 0.3 s, and from 130 degrees at 1.1 s.
constexpr std::array<std::array<float, 3>, 2> kTwoWalkingViews{{{0, 10, 0.3f}, {130, 5, 1.1f}}};

TEST_P(PortraitPsnr, GeometryAndImpostorAgree) {
  REQUIRE_GL();
  std::string path = std::string(BB_SHARED_DATA_DIR) + "/gltf/" + GetParam();
  if (!fs::exists(path)) GTEST_SKIP() << "shared data absent: " << path;
  auto m = load_model(path);
  ASSERT_TRUE(m.ok()) << m.error().message();
  const std::array<float, 3> views[] = {{0, 10, 0.3f}, {40, 5, 0.9f}, {150, 25, 1.4f}, {200, -5, 0.5f}};
  for (const auto& v : views) {
    PortraitOptions o = walking_view(v);
    auto g = render_portrait(*m, o);
    ASSERT_TRUE(g.ok()) << g.error().message();
    o.mode = RenderMode::kImpostor;
    auto i = render_portrait(*m, o);
    ASSERT_TRUE(i.ok()) << i.error().message();
    EXPECT_EQ(g->stats.geometry, 1);
    EXPECT_EQ(i->stats.impostors, 1);
    EXPECT_EQ(i->stats.snapshots, 1);
    int covered = 0;
    double psnr = covered_psnr(*g, *i, &covered);
    std::printf("%s az %.0f el %.0f t %.1f: window %d px, %d covered pixels, PSNR %.2f dB\n", GetParam(), v[0], v[1],
                v[2], i->window_pixels, covered, psnr);
    // SimpleSkin is a single-sided sheet facing +Z: from behind (azimuths 150 and 200) glTF culls it,
    // and neither path draws a pixel of it.
    const bool sheet_from_behind = std::string(GetParam()) == "SimpleSkin.gltf" && std::cos(glm::radians(v[0])) < 0.0f;
    if (sheet_from_behind) {
      EXPECT_EQ(covered, 0) << "a single-sided sheet seen from behind";
      continue;
    }
    EXPECT_GT(covered, 400) << "the character should cover part of the image";
    EXPECT_GT(psnr, 25.0);
    // The paper's orthographic snapshot: off by the perspective of the body's depth at this
    // close range (a sanity bound only; the figure is printed).
    o.orthographic = true;
    auto io = render_portrait(*m, o);
    ASSERT_TRUE(io.ok()) << io.error().message();
    int covered_o = 0;
    double psnr_o = covered_psnr(*g, *io, &covered_o);
    std::printf("%s az %.0f: orthographic snapshot PSNR %.2f dB\n", GetParam(), v[0], psnr_o);
    EXPECT_GT(psnr_o, 8.0);
    if (v[0] == 40) save_ppm_pair(std::string(BB_BIN_DIR) + "/../render_" + fs::path(path).stem().string() + ".ppm", *g, *i);
  }
}

INSTANTIATE_TEST_SUITE_P(SharedModels, PortraitPsnr,
                         ::testing::Values("CesiumMan.glb", "Fox.glb", "RiggedSimple.gltf", "SimpleSkin.gltf"),
                         [](const auto& param_info) { return fs::path(param_info.param).stem().string(); });

// One PortraitRenderer for many pictures (render --frames): each is render_portrait's picture for
// the same options, to the byte, and the renderer is made again only when the size changes.
TEST(PortraitRenderer, ManyPicturesFromOneRendererAreRenderPortraitsOwn) {
  REQUIRE_GL();
  std::string path = std::string(BB_SHARED_DATA_DIR) + "/gltf/CesiumMan.glb";
  if (!fs::exists(path)) GTEST_SKIP() << "shared data absent: " << path;
  auto m = load_model(path);
  ASSERT_TRUE(m.ok()) << m.error().message();
  PortraitRenderer portraits(*m);
  int pictures = 0;
  auto check = [&](const PortraitOptions& o) {
    auto a = portraits.render(o);
    ASSERT_TRUE(a.ok()) << a.error().message();
    auto b = render_portrait(*m, o);
    ASSERT_TRUE(b.ok()) << b.error().message();
    ASSERT_EQ(a->rgba.size(), b->rgba.size());
    EXPECT_TRUE(a->rgba == b->rgba) << "picture " << pictures;
    EXPECT_EQ(a->window_pixels, b->window_pixels);
    EXPECT_EQ(a->stats.snapshots, b->stats.snapshots);
    int covered = 0;
    for (std::size_t i = 3; i < a->rgba.size(); i += 4) covered += a->rgba[i] > 0;
    EXPECT_GT(covered, 400) << "picture " << pictures << ": the character should cover part of it";
    ++pictures;
  };
  PortraitOptions o;
  o.width = o.height = 128;
  for (RenderMode mode : {RenderMode::kImpostor, RenderMode::kGeometry})
    for (int k = 0; k < 4; ++k) {
      o.mode = mode;
      o.time = 0.1f * static_cast<float>(k);  // the clip plays on
      o.azimuth_deg = 25.0f * static_cast<float>(k);
      check(o);
    }
  EXPECT_EQ(portraits.setups(), 1);
  o.width = 96;  // another size: made again
  check(o);
  EXPECT_EQ(portraits.setups(), 2);
}

// The shared models packed by gltfpack (tools/node_modules, npm) as game pipelines ship them:
// KHR_mesh_quantization (integer positions scaled back by the inverse bind matrices, 8-bit normals,
// 12-bit texture coordinates scaled by KHR_texture_transform), EXT_meshopt_compression (-c), with
// octahedral, quaternion and exponential filters (-cc). With the clips kept as they are (-af 0) the
// pictures match the originals' to the quantization; gltfpack's default also resamples the clips at
// 30 Hz with 12-bit rotations, which moves the limbs a little.
struct PackCase {
  const char* args;
  double min_psnr_db;
};

TEST(GltfpackCopies, DrawLikeTheOriginals) {
  REQUIRE_GL();
  const std::string gltfpack = std::string(BB_SOURCE_DIR) + "/tools/node_modules/.bin/gltfpack";
  if (!fs::exists(gltfpack)) GTEST_SKIP() << "gltfpack absent (scripts/setup.sh installs it with npm): " << gltfpack;
  fs::path dir = fs::temp_directory_path() / "bb_gltfpack_test";
  fs::create_directories(dir);
  for (const char* name : {"CesiumMan", "Fox"}) {
    std::string src = std::string(BB_SHARED_DATA_DIR) + "/gltf/" + name + ".glb";
    if (!fs::exists(src)) GTEST_SKIP() << "shared data absent: " << src;
    auto orig = load_model(src);
    ASSERT_TRUE(orig.ok()) << orig.error().message();
    for (const PackCase& pc : {PackCase{"-af 0", 32.0}, PackCase{"-c -af 0", 32.0}, PackCase{"-cc -af 0", 30.0},
                               PackCase{"-cc", 22.0}}) {
      const fs::path out = dir / (std::string(name) + ".glb");
      fs::remove(out);
      const std::string cmd = gltfpack + " -i " + src + " -o " + out.string() + " " + pc.args + " > /dev/null 2>&1";
      ASSERT_EQ(std::system(cmd.c_str()), 0) << cmd;
      auto packed = load_model(out.string());
      ASSERT_TRUE(packed.ok()) << pc.args << ": " << packed.error().message();
      EXPECT_EQ(packed->lods[0].triangle_count(), orig->lods[0].triangle_count()) << pc.args;
      ASSERT_EQ(packed->clips.size(), orig->clips.size()) << pc.args;
      for (std::size_t c = 0; c < orig->clips.size(); ++c) EXPECT_EQ(packed->clips[c].name, orig->clips[c].name);
      EXPECT_NEAR(packed->radius / orig->radius, 1.0, 0.01) << pc.args;
      EXPECT_TRUE(packed->skin_report.weights_normalized) << pc.args;
      double worst = 99.0;
      for (const auto& view : kTwoWalkingViews) {
        const PortraitOptions o = walking_view(view);
        auto a = render_portrait(*orig, o);
        auto b = render_portrait(*packed, o);
        ASSERT_TRUE(a.ok() && b.ok());
        int covered = 0;
        const double psnr = covered_psnr(*a, *b, &covered);
        EXPECT_GT(covered, 400);
        worst = std::min(worst, psnr);
      }
      std::printf("%s packed with gltfpack %s: PSNR against the original %.2f dB (worst of two views)\n", name, pc.args,
                  worst);
      EXPECT_GT(worst, pc.min_psnr_db) << name << " " << pc.args;
    }
  }
}

// The loader's vertex cache order (LoadOptions::optimize_vertex_order) draws the file's picture:
// CesiumMan from two views, walking, against the file's order.
TEST(VertexOrder, CesiumManDrawsTheFilesPicture) {
  REQUIRE_GL();
  LOAD_CESIUM_MAN(ordered);
  LoadOptions file_order;
  file_order.optimize_vertex_order = false;
  auto as_in_file = load_model(path, file_order);
  ASSERT_TRUE(as_in_file.ok());
  for (const auto& view : kTwoWalkingViews) {
    const PortraitOptions o = walking_view(view);
    auto a = render_portrait(*as_in_file, o);
    auto b = render_portrait(*ordered, o);
    ASSERT_TRUE(a.ok() && b.ok());
    int covered = 0, differ = 0;
    const double psnr = covered_psnr(*a, *b, &covered);
    for (std::size_t k = 0; k < a->rgba.size(); ++k) differ += a->rgba[k] != b->rgba[k];
    std::printf("CesiumMan at %.0f degrees: %d of %d covered pixels' channels differ, PSNR %.1f dB\n", view[0], differ, covered,
                psnr);
    EXPECT_GT(covered, 4000);
    EXPECT_GE(psnr, 60.0);
  }
}

}  // namespace
}  // namespace bb::runtime

namespace bb::runtime {
namespace {

// Twenty walkers on rings of 4-6 m, at different phases, and the camera above the ring that
// sees them all (640x512); every character refreshed each frame (both thresholds 0).
Crowd walker_ring(const Model& m) {
  Crowd crowd(m);
  for (int i = 0; i < 20; ++i) {
    float a = 2.0f * 3.14159265f * i / 20.0f, rad = 4.0f + (i % 3);
    crowd.add(Character{glm::vec3(rad * std::sin(a), 0, rad * std::cos(a)), a + 1.5708f, 1.0f, 0, 0.1f * i, 1.0f});
  }
  return crowd;
}
// The texels with coverage of billboard `b`'s window (page pixels `px`, RGBA, of a `page_size`
// page), against the rectangle `r` in window units: how many, how many lie outside it, and the
// margins (texels) between their bounds and its sides (left, bottom, right, top).
struct WindowCoverage {
  int size = 0, covered = 0, outside = 0;
  float margin[4] = {0, 0, 0, 0};
};
WindowCoverage window_coverage(const std::vector<std::uint8_t>& px, int page_size, const BillboardGpu& b, const glm::vec4& r) {
  const float page = static_cast<float>(page_size);
  WindowCoverage w;
  const int x0 = static_cast<int>(std::lround(b.uv_rect.x * page)), y0 = static_cast<int>(std::lround(b.uv_rect.y * page));
  const int size = w.size = static_cast<int>(std::lround((b.uv_rect.z - b.uv_rect.x) * page));
  glm::ivec2 tlo(size), thi(-1);  // the covered texels' bounds
  for (int y = 0; y < size; ++y)
    for (int x = 0; x < size; ++x) {
      if (px[((static_cast<std::size_t>(y0 + y) * page_size) + x0 + x) * 4 + 3] == 0) continue;
      ++w.covered;
      tlo = glm::min(tlo, glm::ivec2(x, y));
      thi = glm::max(thi, glm::ivec2(x, y));
      const glm::vec2 lo = glm::vec2(x, y) / float(size) * 2.0f - 1.0f, hi = glm::vec2(x + 1, y + 1) / float(size) * 2.0f - 1.0f;
      w.outside += lo.x < r.x || lo.y < r.y || hi.x > r.z || hi.y > r.w;
    }
  const float to_texels = 0.5f * static_cast<float>(size);
  w.margin[0] = static_cast<float>(tlo.x) - (r.x + 1.0f) * to_texels;
  w.margin[1] = static_cast<float>(tlo.y) - (r.y + 1.0f) * to_texels;
  w.margin[2] = (r.z + 1.0f) * to_texels - static_cast<float>(thi.x + 1);
  w.margin[3] = (r.w + 1.0f) * to_texels - static_cast<float>(thi.y + 1);
  return w;
}

ImpostorConfig refresh_always() {
  ImpostorConfig cfg;
  cfg.cache.posture_threshold = 0.0f;
  cfg.cache.view_threshold_deg = 0.0f;
  return cfg;
}
SceneCamera ring_camera() {
  SceneCamera cam;
  cam.width = 640;
  cam.height = 512;
  cam.eye = {0, 6, 16};
  cam.target = {0, 0.5f, 0};
  cam.fov_y = glm::radians(45.0f);
  return cam;
}

// The two-model tests' scene: walker i of a file receding from the camera, each overlapping the next,
// and the camera looking down the file.
Character file_walker(int i) { return Character{glm::vec3(0.3f * i - 1.0f, 0, -1.2f * i), 0.3f, 1.0f, 0, 0.13f * i, 1.0f}; }
SceneCamera file_camera() {
  SceneCamera cam;
  cam.width = 640;
  cam.height = 512;
  cam.eye = {0.5f, 1.6f, 4.0f};
  cam.target = {0.3f, 0.9f, -4.0f};
  cam.fov_y = glm::radians(45.0f);
  return cam;
}

// Two models' crowds in one frame (Renderer::draw_many): a file of walkers receding from the
// camera, each overlapping the next, alternately of two models (the same file loaded twice, so
// that one renderer drawing them all is the reference). Blended quads must then be drawn back to
// front across the models: draw_many matches the one-model frame, while drawing model after
// model (the nearer model's quads first) hides the farther walkers under the nearer ones' soft
// edges.
TEST(CrowdRender, SeveralModelsBlendBackToFrontAcrossModels) {
  REQUIRE_GL();
  std::string path = std::string(BB_SHARED_DATA_DIR) + "/gltf/CesiumMan.glb";
  if (!fs::exists(path)) GTEST_SKIP() << "shared data absent: " << path;
  auto m0 = load_model(path);
  auto m1 = load_model(path);
  ASSERT_TRUE(m0.ok() && m1.ok());
  Crowd all(*m0), even(*m0), odd(*m1);
  for (int i = 0; i < 8; ++i) {
    all.add(file_walker(i));
    (i % 2 ? odd : even).add(file_walker(i));
  }
  const ImpostorConfig cfg = refresh_always();
  FramePlanner p_all(*m0, cfg), p_even(*m0, cfg), p_odd(*m1, cfg);
  auto r_all = Renderer::create(*m0, cfg), r_even = Renderer::create(*m0, cfg), r_odd = Renderer::create(*m1, cfg);
  ASSERT_TRUE(r_all.ok() && r_even.ok() && r_odd.ok());
  auto target = OffscreenTarget::create(640, 512);
  ASSERT_TRUE(target.ok());
  const SceneCamera cam = file_camera();
  for (int f = 0; f < 2; ++f) {
    const float t = 0.2f * f;
    (*target)->bind(true);
    const FramePlan& ref = p_all.plan(all, cam, t, RenderMode::kImpostor);
    (*r_all)->draw(ref);
    Image ri{640, 512, (*target)->read_rgba(), ref.stats, 0};
    const FramePlan& pe = p_even.plan(even, cam, t, RenderMode::kImpostor);
    const FramePlan& po = p_odd.plan(odd, cam, t, RenderMode::kImpostor);
    ASSERT_EQ(pe.stats.impostors + po.stats.impostors, 8);
    (*target)->bind(true);
    Renderer* rs[2] = {r_even->get(), r_odd->get()};
    const FramePlan* ps[2] = {&pe, &po};
    Renderer::draw_many(rs, ps);
    Image mi{640, 512, (*target)->read_rgba(), pe.stats, 0};
    (*target)->bind(true);
    (*r_even)->draw(pe, DrawOptions{.take_snapshots = false});  // the nearest walker is even
    (*r_odd)->draw(po, DrawOptions{.take_snapshots = false});
    Image si{640, 512, (*target)->read_rgba(), po.stats, 0};
    int covered = 0;
    const double many = covered_psnr(ri, mi, &covered), in_turn = covered_psnr(ri, si, &covered);
    std::printf("frame %d: %d covered pixels; against one model's frame: draw_many %.2f dB, model after model %.2f dB\n", f,
                covered, many, in_turn);
    EXPECT_GT(covered, 10000);
    EXPECT_GT(many, 45.0);
    EXPECT_GT(many, in_turn + 6.0);
    if (f == 1) save_ppm_pair(std::string(BB_BIN_DIR) + "/../crowd_two_models.ppm", mi, si);
  }
}

// The same two models' file with one atlas for both (shared_atlas_config, Renderer::create's
// share_atlas): draw_many draws every quad in one back-to-front draw, and the frame is the one the
// atlases of their own give with a draw per model and layer. The second model's windows lie in the
// atlas's second half; the atlas outlives the renderer that made it; a config that does not fit it is
// refused.
TEST(CrowdRender, ModelsSharingAnAtlasDrawTheirQuadsInOneDraw) {
  REQUIRE_GL();
  std::string path = std::string(BB_SHARED_DATA_DIR) + "/gltf/CesiumMan.glb";
  if (!fs::exists(path)) GTEST_SKIP() << "shared data absent: " << path;
  auto m0 = load_model(path);
  auto m1 = load_model(path);
  ASSERT_TRUE(m0.ok() && m1.ok());
  Crowd even(*m0), odd(*m1);
  for (int i = 0; i < 8; ++i) (i % 2 ? odd : even).add(file_walker(i));
  ImpostorConfig cfg = refresh_always();
  cfg.max_pages = 4;
  const ImpostorConfig c0 = shared_atlas_config(cfg, 0, 2), c1 = shared_atlas_config(cfg, 1, 2);
  FramePlanner p_even(*m0, cfg), p_odd(*m1, cfg), q_even(*m0, c0), q_odd(*m1, c1);
  auto r_even = Renderer::create(*m0, cfg), r_odd = Renderer::create(*m1, cfg);
  auto s_even = Renderer::create(*m0, c0);
  ASSERT_TRUE(r_even.ok() && r_odd.ok() && s_even.ok());
  auto s_odd = Renderer::create(*m1, c1, s_even->get());
  ASSERT_TRUE(s_odd.ok()) << s_odd.error().reason;
  ImpostorConfig other = c1;
  other.page_size = 512;
  auto refused = Renderer::create(*m1, other, s_even->get());
  ASSERT_FALSE(refused.ok());
  EXPECT_NE(refused.error().reason.find("atlas"), std::string::npos) << refused.error().reason;
  ImpostorConfig outside = c1;
  outside.first_page = 6;  // pages 6 to 9 of 8
  EXPECT_FALSE(Renderer::create(*m1, outside).ok());
  auto target = OffscreenTarget::create(640, 512);
  ASSERT_TRUE(target.ok());
  const SceneCamera cam = file_camera();
  for (int f = 0; f < 2; ++f) {
    const float t = 0.2f * f;
    const FramePlan& pe = p_even.plan(even, cam, t, RenderMode::kImpostor);
    const FramePlan& po = p_odd.plan(odd, cam, t, RenderMode::kImpostor);
    const FramePlan& qe = q_even.plan(even, cam, t, RenderMode::kImpostor);
    const FramePlan& qo = q_odd.plan(odd, cam, t, RenderMode::kImpostor);
    ASSERT_EQ(qo.billboards.size(), 4u);
    for (const BillboardGpu& b : qo.billboards) {
      EXPECT_GE(b.layer.x, 4.0f);
      EXPECT_LT(b.layer.x, 8.0f);
    }
    for (const BillboardGpu& b : qe.billboards) EXPECT_LT(b.layer.x, 4.0f);
    (*target)->bind(true);
    Renderer* rs[2] = {r_even->get(), r_odd->get()};
    const FramePlan* ps[2] = {&pe, &po};
    Renderer::draw_many(rs, ps);
    Image own{640, 512, (*target)->read_rgba(), pe.stats, 0};
    (*target)->bind(true);
    Renderer* ss[2] = {s_even->get(), s_odd->get()};
    const FramePlan* qs[2] = {&qe, &qo};
    Renderer::draw_many(ss, qs);
    Image shared{640, 512, (*target)->read_rgba(), qe.stats, 0};
    int covered = 0, differ = 0;
    for (std::size_t i = 0; i < own.rgba.size(); ++i) differ += own.rgba[i] != shared.rgba[i];
    for (std::size_t i = 3; i < own.rgba.size(); i += 4) covered += own.rgba[i] > 0;
    std::printf("frame %d: %d covered pixels, %d bytes differ between one atlas and two\n", f, covered, differ);
    EXPECT_GT(covered, 10000);
    EXPECT_EQ(differ, 0);
  }
  // The atlas lives on with the renderer that shares it: the odd walkers alone, drawn again.
  s_even->reset();
  (*target)->bind(true);
  const FramePlan& qo = q_odd.plan(odd, cam, 0.4f, RenderMode::kImpostor);
  (*s_odd)->draw(qo);
  const std::vector<std::uint8_t> px = (*target)->read_rgba();
  int covered = 0;
  for (std::size_t i = 3; i < px.size(); i += 4) covered += px[i] > 0;
  EXPECT_GT(covered, 4000);
}

// An atlas too big for one texture: llvmpipe (Mesa 22.3) makes none over 2 GB (512 pages of 1024 x
// 1024 RGBA8), and create() says so, naming the atlas and its pages, instead of drawing into an
// incomplete framebuffer (flow then gives each model an atlas of its own). A GPU may make it.
TEST(CrowdRender, AnAtlasTooBigForOneTextureIsRefusedWithItsSize) {
  REQUIRE_GL();
  LOAD_CESIUM_MAN(m);
  ImpostorConfig cfg;
  cfg.atlas_pages = 600;  // 2.3 GB of colour
  auto r = Renderer::create(*m, cfg);
  // A GPU, or a llvmpipe with a higher limit than Mesa 22.3's 2 GB, makes it: nothing to refuse there.
  if (r.ok()) GTEST_SKIP() << "this GL makes a texture of 600 pages of 1024 x 1024 (" << (software_rasterizer() ? "software" : "GPU") << ")";
  EXPECT_EQ(r.error().where, "atlas");
  EXPECT_NE(r.error().reason.find("600 pages of 1024 x 1024"), std::string::npos) << r.error().reason;
  cfg.atlas_pages = 64;  // and the next renderer is made as if nothing had happened
  cfg.max_pages = 32;
  EXPECT_TRUE(Renderer::create(*m, cfg).ok());
}

// A page smaller than the largest window holds none of it (each page is a grid of one size): the
// renderer refuses the config, naming the setting, instead of the first impostor frame crashing.
TEST(CrowdRender, APageSmallerThanTheLargestWindowIsRefused) {
  REQUIRE_GL();
  LOAD_CESIUM_MAN(m);
  ImpostorConfig cfg;
  cfg.page_size = 128;
  auto r = Renderer::create(*m, cfg);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.error().where, "ImpostorConfig::page_size");
  EXPECT_NE(r.error().reason.find("largest window (256"), std::string::npos) << r.error().reason;
  cfg.max_pages = 0;
  cfg.page_size = 1024;
  r = Renderer::create(*m, cfg);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.error().where, "ImpostorConfig::max_pages");
  cfg.max_pages = 2;
  cfg.windows.size[5] = 0;
  r = Renderer::create(*m, cfg);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.error().where, "ImpostorConfig::windows");
}

// Three walkers 6 m away in a 320x240 frame (the GL state tests').
Crowd three_walkers(const Model& m) {
  Crowd crowd(m);
  for (int i = 0; i < 3; ++i)
    crowd.add(Character{glm::vec3(1.2f * static_cast<float>(i - 1), 0, 0), 0.5f * static_cast<float>(i), 1.0f, 0,
                        0.3f * static_cast<float>(i), 1.0f});
  return crowd;
}
SceneCamera three_walkers_camera() {
  SceneCamera cam;
  cam.eye = {0, 1.2f, 6};
  cam.target = {0, 0.8f, 0};
  cam.width = 320;
  cam.height = 240;
  return cam;
}

// A game may call draw() with its own state on: a scissor rectangle (its UI's), polygon offset (its
// decals'). They are of its framebuffer: the scene's passes take them, but the snapshots drawn into
// the atlas must not (a picture cut by the scissor, or offset, is drawn from the atlas until a cache
// test fires), and the game finds its state as it left it.
TEST(CrowdRender, SnapshotsIgnoreTheGamesScissorAndPolygonOffset) {
  REQUIRE_GL();
  LOAD_CESIUM_MAN(m);
  const Crowd crowd = three_walkers(*m);
  const SceneCamera cam = three_walkers_camera();
  auto target = OffscreenTarget::create(320, 240);
  ASSERT_TRUE(target.ok());
  struct Case {
    const char* name;
    bool scissor, offset;
    int samples;
  };
  for (const Case& c : {Case{"scissor", true, false, 1}, Case{"polygon offset", false, true, 1},
                        Case{"both, multisampled snapshots", true, true, 4}}) {
    SCOPED_TRACE(c.name);
    ImpostorConfig cfg;
    cfg.snapshot_samples = c.samples;
    auto frame = [&](FramePlanner& planner, Renderer& renderer, bool game_state) {
      (*target)->bind(true);
      if (game_state && c.scissor) {
        glEnable(GL_SCISSOR_TEST);
        glScissor(0, 0, 160, 240);  // the left half of the screen
      }
      if (game_state && c.offset) {
        glEnable(GL_POLYGON_OFFSET_FILL);
        glPolygonOffset(4.0f, 4.0f);
      }
      const FramePlan& plan = planner.plan(crowd, cam, 1.0f, RenderMode::kImpostor);
      while (glGetError() != GL_NO_ERROR) {
      }
      renderer.draw(plan);
      EXPECT_EQ(glGetError(), static_cast<GLenum>(GL_NO_ERROR));
      if (game_state) {  // as the game left it
        EXPECT_EQ(glIsEnabled(GL_SCISSOR_TEST), c.scissor ? GL_TRUE : GL_FALSE);
        EXPECT_EQ(glIsEnabled(GL_POLYGON_OFFSET_FILL), c.offset ? GL_TRUE : GL_FALSE);
        GLint box[4];
        glGetIntegerv(GL_SCISSOR_BOX, box);
        if (c.scissor) {
          EXPECT_EQ(box[2], 160);
        }
        GLfloat units = 0;
        glGetFloatv(GL_POLYGON_OFFSET_UNITS, &units);
        if (c.offset) {
          EXPECT_EQ(units, 4.0f);
        }
        glDisable(GL_SCISSOR_TEST);
        glDisable(GL_POLYGON_OFFSET_FILL);
        glPolygonOffset(0.0f, 0.0f);
      }
      return Image{320, 240, (*target)->read_rgba(), plan.stats, 0};
    };
    FramePlanner ref_planner(*m, cfg), planner(*m, cfg);
    auto ref_renderer = Renderer::create(*m, cfg);
    auto renderer = Renderer::create(*m, cfg);
    ASSERT_TRUE(ref_renderer.ok() && renderer.ok());
    const Image ref = frame(ref_planner, **ref_renderer, false);
    ASSERT_EQ(ref.stats.snapshots, 3);
    const Image with_state = frame(planner, **renderer, true);
    ASSERT_EQ(with_state.stats.snapshots, 3);
    if (c.scissor) {  // the scene's pass took the game's scissor: nothing right of it
      long right = 0;
      for (int y = 0; y < 240; ++y)
        for (int x = 160; x < 320; ++x) right += with_state.rgba[(static_cast<std::size_t>(y) * 320 + x) * 4 + 3] != 0;
      EXPECT_EQ(right, 0);
    }
    // The next frame draws the snapshots taken under the game's state: the same as the reference's.
    const Image cached = frame(planner, **renderer, false);
    EXPECT_EQ(cached.stats.snapshots, 0);
    int covered = 0;
    const double psnr = covered_psnr(ref, cached, &covered);
    EXPECT_GT(covered, 2000);
    EXPECT_GT(psnr, 60.0) << "the cached snapshots differ from those taken without the game's state";
  }
}

// A planner's snapshots are pictures in the atlas of the renderer that drew its plans. A renderer
// made anew (after a context loss, a change of settings) holds none of them: the planner's next
// plans would draw empty windows (invisible characters) until their cache tests fire. The plan
// names its cache, and the renderer tells whether it holds its snapshots; FramePlanner::invalidate
// starts a new cache that any renderer can draw.
TEST(CrowdRender, ANewRendererTakesThePlannersSnapshotsAnew) {
  REQUIRE_GL();
  LOAD_CESIUM_MAN(m);
  const Crowd crowd = three_walkers(*m);
  const SceneCamera cam = three_walkers_camera();
  auto target = OffscreenTarget::create(320, 240);
  ASSERT_TRUE(target.ok());
  FramePlanner planner(*m);
  auto first = Renderer::create(*m);
  ASSERT_TRUE(first.ok());
  auto draw = [&](Renderer& r, const FramePlan& plan) {
    (*target)->bind(true);
    r.draw(plan);
    return Image{320, 240, (*target)->read_rgba(), plan.stats, 0};
  };
  const FramePlan& p0 = planner.plan(crowd, cam, 1.0f, RenderMode::kImpostor);
  EXPECT_EQ(p0.cache_plans_before, 0u);
  const std::uint64_t cache = p0.cache_id;
  const Image a = draw(**first, p0);
  const FramePlan& p1 = planner.plan(crowd, cam, 1.0f, RenderMode::kImpostor);
  EXPECT_EQ(p1.stats.snapshots, 0);
  EXPECT_EQ(p1.cache_id, cache);
  EXPECT_EQ(p1.cache_plans_before, 1u);
  EXPECT_TRUE((*first)->holds_snapshots_for(p1));
  auto second = Renderer::create(*m);
  ASSERT_TRUE(second.ok());
  EXPECT_FALSE((*second)->holds_snapshots_for(p1));  // drawing it would show three empty windows
  planner.invalidate();
  const FramePlan& p2 = planner.plan(crowd, cam, 1.0f, RenderMode::kImpostor);
  EXPECT_NE(p2.cache_id, cache);
  EXPECT_EQ(p2.cache_plans_before, 0u);
  EXPECT_EQ(p2.stats.snapshots, 3);
  EXPECT_TRUE((*second)->holds_snapshots_for(p2));
  const Image b = draw(**second, p2);
  const FramePlan& p3 = planner.plan(crowd, cam, 1.0f, RenderMode::kImpostor);
  EXPECT_TRUE((*second)->holds_snapshots_for(p3));
  EXPECT_FALSE((*first)->holds_snapshots_for(p3));  // the first renderer holds the old cache's
  const Image c = draw(**second, p3);
  int covered = 0;
  EXPECT_GT(covered_psnr(a, b, &covered), 60.0);
  EXPECT_GT(covered, 2000);
  EXPECT_GT(covered_psnr(a, c, &covered), 60.0);
  // Another planner's plans: a first plan needs nothing of the renderer; its next ones do.
  FramePlanner other(*m);
  const FramePlan& q0 = other.plan(crowd, cam, 1.0f, RenderMode::kImpostor);
  EXPECT_NE(q0.cache_id, p3.cache_id);
  EXPECT_TRUE((*second)->holds_snapshots_for(q0));
  EXPECT_FALSE((*second)->holds_snapshots_for(other.plan(crowd, cam, 1.0f, RenderMode::kImpostor)));
  // Without invalidate(): the new renderer draws one frame of empty windows and marks the plan, and
  // the planner takes every snapshot anew at its next frame (it drew them empty until their cache
  // tests fired, for good in a still scene).
  auto third = Renderer::create(*m);
  ASSERT_TRUE(third.ok());
  const FramePlan& p4 = planner.plan(crowd, cam, 1.0f, RenderMode::kImpostor);
  EXPECT_EQ(p4.stats.snapshots, 0);
  (void)draw(**third, p4);
  EXPECT_TRUE(p4.drawn_from_another_atlas);
  const FramePlan& p5 = planner.plan(crowd, cam, 1.0f, RenderMode::kImpostor);
  EXPECT_EQ(p5.stats.snapshots, 3);
  EXPECT_FALSE(p5.drawn_from_another_atlas);
  EXPECT_TRUE((*third)->holds_snapshots_for(p5));
  EXPECT_GT(covered_psnr(a, draw(**third, p5), &covered), 60.0);
  EXPECT_GT(covered, 2000);
}

// Twenty walkers on a circle seen from above the ring: the crowd path (planner + renderer) with
// every character refreshed each frame, compared with geometry frame by frame.
TEST(CrowdRender, ImpostorFramesMatchGeometryFrames) {
  REQUIRE_GL();
  LOAD_CESIUM_MAN(m);
  Crowd crowd = walker_ring(*m);
  const ImpostorConfig cfg = refresh_always();
  FramePlanner planner(*m, cfg);
  auto renderer = Renderer::create(*m, cfg);
  ASSERT_TRUE(renderer.ok()) << renderer.error().message();
  auto target = OffscreenTarget::create(640, 512);
  ASSERT_TRUE(target.ok());
  const SceneCamera cam = ring_camera();
  for (int f = 0; f < 3; ++f) {
    float t = 0.1f * f;
    (*target)->bind(true);
    const FramePlan& g = planner.plan(crowd, cam, t, RenderMode::kGeometry);
    EXPECT_EQ(g.stats.geometry, 20);
    (*renderer)->draw(g);
    Image gi{640, 512, (*target)->read_rgba(), g.stats, 0};
    (*target)->bind(true);
    const FramePlan& p = planner.plan(crowd, cam, t, RenderMode::kImpostor);
    EXPECT_EQ(p.stats.impostors, 20);
    EXPECT_EQ(p.stats.snapshots, 20);  // thresholds 0: every character, every frame
    (*renderer)->draw(p);
    Image ii{640, 512, (*target)->read_rgba(), p.stats, 0};
    int covered = 0;
    double psnr = covered_psnr(gi, ii, &covered);
    std::printf("crowd frame %d: %d covered pixels, PSNR %.2f dB, atlas pages %d\n", f, covered, psnr,
                p.stats.atlas_pages_used);
    EXPECT_GT(covered, 5000);
    // Characters ~50 pixels tall in 64-pixel windows: bilinear resampling of aliased edges
    // bounds the agreement (measured ~18 dB on llvmpipe); a regression shows as a collapse.
    EXPECT_GT(psnr, 15.0);
    if (f == 2) save_ppm_pair(std::string(BB_BIN_DIR) + "/../crowd_CesiumMan.ppm", gi, ii);
  }
}

// Characters a game scales between frames keep their snapshots, drawn at their new size: standing
// walkers, view test only, every one 8 % larger after its snapshot agrees with the geometry about as
// well as before.
TEST(CrowdRender, ScaledCharactersImpostorsMatchTheirGeometry) {
  REQUIRE_GL();
  LOAD_CESIUM_MAN(m);
  Crowd crowd = walker_ring(*m);
  for (Character& c : crowd.characters()) c.speed = 0.0f;
  ImpostorConfig cfg;
  cfg.cache.posture_test = false;
  FramePlanner planner(*m, cfg);
  auto renderer = Renderer::create(*m, cfg);
  ASSERT_TRUE(renderer.ok()) << renderer.error().message();
  auto target = OffscreenTarget::create(640, 512);
  ASSERT_TRUE(target.ok());
  const SceneCamera cam = ring_camera();
  auto frame = [&](RenderMode mode, int* snapshots) {
    (*target)->bind(true);
    const FramePlan& p = planner.plan(crowd, cam, 0.0f, mode);
    if (snapshots) *snapshots = p.stats.snapshots;
    (*renderer)->draw(p);
    return Image{640, 512, (*target)->read_rgba(), p.stats, 0};
  };
  int snapshots = 0, covered = 0;
  const Image i0 = frame(RenderMode::kImpostor, &snapshots);
  EXPECT_EQ(snapshots, 20);
  const double before = covered_psnr(frame(RenderMode::kGeometry, nullptr), i0, &covered);
  for (Character& c : crowd.characters()) c.scale = 1.08f;
  const Image i1 = frame(RenderMode::kImpostor, &snapshots);
  const double after = covered_psnr(frame(RenderMode::kGeometry, nullptr), i1, &covered);
  std::printf("scaled characters: %d snapshots, PSNR %.2f dB before, %.2f dB 8 %% larger\n", snapshots, before, after);
  EXPECT_LT(snapshots, 20);  // most keep their window
  EXPECT_GT(after, before - 1.5);
}

// A far crowd of characters a few pixels high: with the default window sizes they take 16- and
// 8-pixel windows, a fraction of the atlas the paper's 32-pixel smallest windows would take, and
// at the same texels per pixel their impostors agree with the geometry as well.
TEST(CrowdRender, SmallCharactersTakeSmallWindows) {
  REQUIRE_GL();
  LOAD_CESIUM_MAN(m);
  Crowd crowd(*m);
  for (int i = 0; i < 400; ++i) {  // a 20 x 20 grid, 120 to 158 m away
    const float x = -19.0f + 2.0f * static_cast<float>(i % 20), z = -120.0f - 2.0f * static_cast<float>(i / 20);
    crowd.add(Character{glm::vec3(x, 0, z), 0.3f * i, 1.0f, 0, 0.05f * i, 1.0f});
  }
  SceneCamera cam = ring_camera();
  cam.eye = {0, 4, 0};
  cam.target = {0, 0.5f, -140};
  auto target = OffscreenTarget::create(640, 512);
  ASSERT_TRUE(target.ok());
  struct Run {
    FrameStats stats;
    double psnr = 0;
  };
  auto run = [&](const WindowSizes& windows, bool part_cards = false) {
    ImpostorConfig cfg = refresh_always();
    cfg.windows = windows;
    cfg.part_cards = part_cards;
    cfg.texels_per_pixel = 1.0f;  // the flow test bed's: exactly 1 texel per pixel
    cfg.texel_per_pixel = true;
    FramePlanner planner(*m, cfg);
    auto renderer = Renderer::create(*m, cfg);
    EXPECT_TRUE(renderer.ok());
    if (!renderer.ok()) return Run{};
    (*target)->bind(true);
    (*renderer)->draw(planner.plan(crowd, cam, 0.4f, RenderMode::kGeometry));
    Image gi{640, 512, (*target)->read_rgba(), {}, 0};
    (*target)->bind(true);
    const FramePlan& p = planner.plan(crowd, cam, 0.4f, RenderMode::kImpostor);
    (*renderer)->draw(p);
    Image ii{640, 512, (*target)->read_rgba(), p.stats, 0};
    int covered = 0;
    Run r{p.stats, covered_psnr(gi, ii, &covered)};
    EXPECT_GT(covered, 1500);
    EXPECT_EQ(p.stats.impostors, 400);
    return r;
  };
  const WindowSizes small;  // the default: down to 8
  WindowSizes paper;
  paper.count = 4;  // 256 .. 32
  const Run a = run(small), b = run(paper);
  auto window_texels = [](const Run& r, const WindowSizes& w) {
    long n = 0;
    for (int k = 0; k < w.count; ++k) n += static_cast<long>(r.stats.impostors_per_window[k]) * w.size[k] * w.size[k];
    return n;
  };
  const long ta = window_texels(a, small), tb = window_texels(b, paper);
  std::printf("small windows: per class %d %d %d %d %d %d, %ld window texels, PSNR %.2f dB; the paper's: %ld texels, "
              "PSNR %.2f dB\n",
              a.stats.impostors_per_window[0], a.stats.impostors_per_window[1], a.stats.impostors_per_window[2],
              a.stats.impostors_per_window[3], a.stats.impostors_per_window[4], a.stats.impostors_per_window[5], ta,
              a.psnr, tb, b.psnr);
  EXPECT_GT(a.stats.impostors_per_window[4] + a.stats.impostors_per_window[5], 300);
  EXPECT_EQ(b.stats.impostors_per_window[3], 400);
  EXPECT_LT(4 * ta, tb);  // the same pictures in a quarter of the atlas or less
  EXPECT_NEAR(a.psnr, b.psnr, 0.1);
  // Part cards keep the paper's smallest window (ImpostorConfig::smallest_part_window).
  const Run c = run(small, true);
  std::printf("part cards: %d cards, per class %d %d %d %d %d %d\n", c.stats.part_cards, c.stats.impostors_per_window[0],
              c.stats.impostors_per_window[1], c.stats.impostors_per_window[2], c.stats.impostors_per_window[3],
              c.stats.impostors_per_window[4], c.stats.impostors_per_window[5]);
  EXPECT_GT(c.stats.part_cards, 400);
  EXPECT_EQ(c.stats.impostors_per_window[3], c.stats.part_cards);
}

// DrawOptions::flush_every_indices splits the instanced draws of the geometry and of the
// snapshots and flushes between them: the frames must not change by a bit, whether every
// instance is flushed alone, a few at a time, or none. Part cards draw ranges of the parts'
// indices, the other split.
TEST(CrowdRender, FlushesLeaveTheFramesAsTheyWere) {
  REQUIRE_GL();
  LOAD_CESIUM_MAN(m);
  Crowd crowd = walker_ring(*m);
  const SceneCamera cam = ring_camera();
  auto target = OffscreenTarget::create(640, 512);
  ASSERT_TRUE(target.ok());
  for (bool parts : {false, true}) {
    ImpostorConfig cfg = refresh_always();
    cfg.part_cards = parts;
    // One planner and renderer per flush setting, fed the same frames: every snapshot is due in
    // every frame (thresholds 0), so each frame draws all of them.
    const int settings[3] = {0, 1, 30000};
    std::vector<std::unique_ptr<FramePlanner>> planners;
    std::vector<std::unique_ptr<Renderer>> renderers;
    for (int k = 0; k < 3; ++k) {
      planners.push_back(std::make_unique<FramePlanner>(*m, cfg));
      auto r = Renderer::create(*m, cfg);
      ASSERT_TRUE(r.ok()) << r.error().message();
      renderers.push_back(std::move(*r));
    }
    for (int f = 0; f < 2; ++f) {
      const float t = 0.1f * static_cast<float>(f);
      for (RenderMode mode : {RenderMode::kGeometry, RenderMode::kImpostor}) {
        std::vector<std::uint8_t> frames[3];
        for (int k = 0; k < 3; ++k) {
          (*target)->bind(true);
          const FramePlan& plan = planners[k]->plan(crowd, cam, t, mode);
          if (mode == RenderMode::kImpostor) {
            EXPECT_EQ(plan.stats.snapshots, 20);
          }
          DrawOptions opt;
          opt.flush_every_indices = settings[k];
          renderers[k]->draw(plan, opt);
          frames[k] = (*target)->read_rgba();
        }
        long covered = 0;
        for (std::size_t i = 3; i < frames[0].size(); i += 4) covered += frames[0][i] > 0;
        EXPECT_GT(covered, 5000);
        for (int k = 1; k < 3; ++k)
          EXPECT_TRUE(frames[k] == frames[0]) << "parts " << parts << ", frame " << f << ", "
                                              << (mode == RenderMode::kGeometry ? "geometry" : "impostors")
                                              << ", a flush every " << settings[k] << " indices";
      }
    }
  }
}

// ImpostorConfig::short_lived_as_geometry with both thresholds 0: from the second impostor frame
// every character is drawn as geometry, and the impostor frame is the geometry frame to the bit
// (a single-sampled target, as the flow test bed gives both paths at --msaa 1).
TEST(CrowdRender, ShortLivedCharactersAreTheGeometrysPicture) {
  REQUIRE_GL();
  LOAD_CESIUM_MAN(m);
  Crowd crowd = walker_ring(*m);
  const SceneCamera cam = ring_camera();
  auto target = OffscreenTarget::create(640, 512);
  ASSERT_TRUE(target.ok());
  for (bool parts : {false, true}) {
    ImpostorConfig cfg = refresh_always();
    cfg.part_cards = parts;
    cfg.short_lived_as_geometry = true;
    FramePlanner planner(*m, cfg);
    auto r = Renderer::create(*m, cfg);
    ASSERT_TRUE(r.ok()) << r.error().message();
    for (int f = 0; f < 3; ++f) {
      const float t = 0.1f * static_cast<float>(f);
      std::vector<std::uint8_t> frames[2];
      for (RenderMode mode : {RenderMode::kGeometry, RenderMode::kImpostor}) {
        (*target)->bind(true);
        const FramePlan& plan = planner.plan(crowd, cam, t, mode);
        if (mode == RenderMode::kImpostor) {
          EXPECT_EQ(plan.stats.short_lived_geometry, f == 0 ? 0 : 20) << f;
          EXPECT_EQ(plan.stats.snapshots, f == 0 ? 20 : 0) << f;
        }
        (*r)->draw(plan);
        frames[mode == RenderMode::kGeometry ? 0 : 1] = (*target)->read_rgba();
      }
      long covered = 0, differ = 0;
      for (std::size_t i = 3; i < frames[0].size(); i += 4) covered += frames[0][i] > 0;
      for (std::size_t i = 0; i < frames[0].size(); ++i) differ += frames[0][i] != frames[1][i];
      EXPECT_GT(covered, 5000);
      if (f == 0)
        EXPECT_GT(differ, 100) << "parts " << parts;  // the first frame's are snapshots
      else
        EXPECT_EQ(differ, 0) << "parts " << parts << ", frame " << f;
    }
  }
}

}  // namespace
}  // namespace bb::runtime

namespace bb::runtime {
namespace {

// A white 1 m square facing +Z, turned 30 degrees about Z so that its edges cross pixels at all
// phases; no vertex moves (all on the root joint), so a snapshot is exact apart from resampling.
Model square_model() {
  Model m;
  m.nodes = {Node{"root", -1, {}}, Node{"arm", 0, {glm::vec3(0, 1, 0), glm::quat(1, 0, 0, 0), glm::vec3(1)}}};
  m.palette = {PaletteEntry{0, glm::mat4(1)}, PaletteEntry{1, glm::mat4(1)}};
  MeshLod lod;
  const float c = std::cos(glm::radians(30.0f)), s = std::sin(glm::radians(30.0f));
  const glm::vec2 corners[4] = {{-0.5f, -0.5f}, {0.5f, -0.5f}, {0.5f, 0.5f}, {-0.5f, 0.5f}};
  for (const glm::vec2& k : corners) {
    Vertex v;
    v.position = {c * k.x - s * k.y, 1.0f + s * k.x + c * k.y, 0.0f};
    v.normal = {0, 0, 1};
    lod.vertices.push_back(v);
  }
  lod.indices = {0, 1, 2, 0, 2, 3};
  lod.primitives = {Primitive{0, 6, 0}};
  m.lods = {lod};
  m.materials = {Material{}};
  Clip clip;
  clip.name = "still";
  clip.duration = 1.0f;
  Channel ch;
  ch.node = 1;
  ch.path = ChannelPath::kTranslation;
  ch.times = {0.0f, 1.0f};
  ch.values = {{0, 1, 0, 0}, {0, 1, 0, 0}};
  clip.channels = {ch};
  m.clips = {clip};
  m.bake(30.0f);
  return m;
}

// `m` alone, fresh (both thresholds 0; `cfg` may change the rest), drawn into a 128 x 128 target at 4x MSAA, a square_model about
// 60 pixels wide: frame() draws one path and gives its RGBA pixels.
// A 128x128 camera looking down -Z at the model's Ta, from where a metre there spans `pixels`.
SceneCamera square_camera(const Model& m, float pixels) {
  SceneCamera cam;
  cam.width = cam.height = 128;
  cam.target = m.ta;
  cam.eye = m.ta + glm::vec3(0, 0, cam.pixels_per_metre(1.0f) / pixels);
  return cam;
}

struct SquareScene {
  explicit SquareScene(const Model& model, const ImpostorConfig& cfg = fresh(), float pixels_per_metre = 60.0f)
      : m(model), config(cfg), crowd(model), planner(model, cfg), cam(square_camera(model, pixels_per_metre)) {
    crowd.add(Character{});
    auto r = Renderer::create(m, cfg);
    EXPECT_TRUE(r.ok()) << r.error().message();
    if (r.ok()) renderer = std::move(*r);
    auto t = OffscreenTarget::create(128, 128, 4);
    EXPECT_TRUE(t.ok());
    if (t.ok()) target = std::move(*t);
  }
  // Every snapshot taken anew each frame (relit ones with `relight`).
  static ImpostorConfig fresh() { return fresh(false); }
  static ImpostorConfig fresh(bool relight) {
    ImpostorConfig cfg;
    cfg.cache.posture_threshold = 0.0f;
    cfg.cache.view_threshold_deg = 0.0f;
    cfg.relight = relight;
    return cfg;
  }
  bool ok() const { return renderer && target; }
  std::vector<std::uint8_t> frame(RenderMode mode, const DrawOptions& o = {}) {
    target->bind(true);
    renderer->draw(planner.plan(crowd, cam, 0.0f, mode), o);
    return target->read_rgba();
  }
  // A frame of a crowd of these characters, in this order, with snapshots of their own (and its
  // plan's figures in `stats`).
  std::vector<std::uint8_t> frame_of(const std::vector<Character>& characters, RenderMode mode,
                                     FrameStats* stats = nullptr) {
    Crowd c(m);
    for (const Character& ch : characters) c.add(ch);
    FramePlanner p(m, config);
    target->bind(true);
    const FramePlan& plan = p.plan(c, cam, 0.0f, mode);
    if (stats) *stats = plan.stats;
    renderer->draw(plan);
    return target->read_rgba();
  }
  const Model& m;
  ImpostorConfig config;
  Crowd crowd;
  FramePlanner planner;
  std::unique_ptr<Renderer> renderer;
  std::unique_ptr<OffscreenTarget> target;
  SceneCamera cam;
};

struct EdgeCounts {
  int opaque = 0, partial = 0;
  int opaque_off = 0;      // opaque pixels whose colour is not the flat colour
  int fringe = 0;          // partial pixels whose colour is not flat x coverage (4 levels)
  int not_premultiplied = 0;  // partial pixels with a channel above alpha
};

EdgeCounts count_edges(const std::vector<std::uint8_t>& px, int flat) {
  EdgeCounts e;
  for (std::size_t i = 0; i < px.size(); i += 4) {
    const int a = px[i + 3];
    if (a == 0) continue;
    if (a == 255) {
      ++e.opaque;
      for (int k = 0; k < 3; ++k) e.opaque_off += px[i + k] != flat;
      continue;
    }
    ++e.partial;
    for (int k = 0; k < 3; ++k) {
      e.not_premultiplied += px[i + k] > a;
      // Premultiplied: colour = flat x coverage, within 4 levels (the straight colour of a pixel
      // with one sample of four covered comes from a small filtered alpha: a few % off).
      e.fringe += std::abs(px[i + k] - flat * a / 255.0) > 4.0;
    }
  }
  return e;
}

// Multisampled target: the impostor's edges carry coverage like the geometry's, with the flat
// colour straight (premultiplied by coverage, no dark or bright fringe); the alpha test gives none.
TEST(ImpostorEdges, CoverageLikeMultisampledGeometryWithoutFringes) {
  REQUIRE_GL();
  const Model m = square_model();
  SquareScene scene(m);
  ASSERT_TRUE(scene.ok());
  auto frame = [&](RenderMode mode, const DrawOptions& o) { return scene.frame(mode, o); };
  const auto geometry = frame(RenderMode::kGeometry, {});
  // Lighting 0.35 + 0.65 n.l with n = +Z and l = unit(0.4, 0.8, 0.6): 0.7121 of white -> 182.
  const int flat = 182;
  const EdgeCounts g = count_edges(geometry, flat);
  EXPECT_GT(g.opaque, 2000);
  EXPECT_GT(g.partial, 100);  // the multisampled geometry's edges
  EXPECT_EQ(g.opaque_off, 0);
  EXPECT_EQ(g.fringe, 0);
  EXPECT_EQ(g.not_premultiplied, 0);
  auto area = [](const std::vector<std::uint8_t>& px) {
    double sum = 0;
    for (std::size_t i = 3; i < px.size(); i += 4) sum += px[i] / 255.0;
    return sum;
  };
  Image gi{128, 128, geometry, {}, 0};
  const std::pair<ImpostorEdges, const char*> modes[] = {{ImpostorEdges::kBlend, "blend"},
                                                         {ImpostorEdges::kSamples, "samples"},
                                                         {ImpostorEdges::kAlphaToCoverage, "alpha to coverage"},
                                                         {ImpostorEdges::kAlphaTest, "alpha test"}};
  double psnr_test = 0;
  std::vector<double> psnr_soft;
  for (const auto& [edges, name] : modes) {
    DrawOptions o;
    o.edges = edges;
    const auto im = frame(RenderMode::kImpostor, o);
    const EdgeCounts c = count_edges(im, flat);
    Image ii{128, 128, im, {}, 0};
    int covered = 0;
    const double psnr = covered_psnr(gi, ii, &covered);
    std::printf("%s: %d opaque, %d partial (geometry %d, %d), PSNR %.2f dB\n", name, c.opaque, c.partial, g.opaque,
                g.partial, psnr);
    EXPECT_EQ(c.opaque_off, 0) << name;
    EXPECT_EQ(c.fringe, 0) << name;
    EXPECT_EQ(c.not_premultiplied, 0) << name;
    if (edges == ImpostorEdges::kAlphaTest) {
      EXPECT_EQ(c.partial, 0);  // all of a pixel's samples or none
      psnr_test = psnr;
      continue;
    }
    EXPECT_GT(c.partial, g.partial / 2) << name;
    EXPECT_LT(c.partial, g.partial * 3) << name;  // blending's four taps: a softer edge
    EXPECT_NEAR(area(im), area(geometry), 0.02 * area(geometry)) << name;
    EXPECT_GT(psnr, 28.0) << name;  // measured 30-35 dB on llvmpipe
    psnr_soft.push_back(psnr);
  }
  for (double p : psnr_soft) EXPECT_GT(p, psnr_test + 5.0);
  // Blended quads are drawn single-sampled; draw() leaves multisampling on as it found it, so the
  // geometry frame after all of them is the same to the byte.
  EXPECT_EQ(frame(RenderMode::kGeometry, {}), geometry);
}

// At one texel per pixel, ImpostorConfig::impostor_taps picks how a blended impostor's edge pixel
// gets its coverage in a 4x multisampled scene: four taps at the 4x pattern, two on the diagonal,
// or one. Each keeps the square's area and its flat colour premultiplied; the soft edges of two
// and four taps agree with the multisampled geometry better than one tap's, two within a little of
// four.
TEST(ImpostorEdges, TwoTapsNearlyMatchFourAtOneTexelPerPixel) {
  REQUIRE_GL();
  Model m = square_model();
  Crowd crowd(m);
  crowd.add(Character{});  // a square turned 30 degrees on screen
  auto target = OffscreenTarget::create(128, 128, 4);
  ASSERT_TRUE(target.ok());
  const SceneCamera cam = square_camera(m, 60.0f);
  std::vector<std::uint8_t> geometry;
  double psnr[5] = {};
  for (int taps : {0, 1, 2, 4}) {  // 0: the geometry frame
    ImpostorConfig cfg;
    cfg.cache.posture_threshold = 0.0f;
    cfg.cache.view_threshold_deg = 0.0f;
    cfg.texels_per_pixel = 1.0f;
    cfg.impostor_taps = taps;
    FramePlanner planner(m, cfg);
    auto renderer = Renderer::create(m, cfg);
    ASSERT_TRUE(renderer.ok()) << renderer.error().message();
    (*target)->bind(true);
    (*renderer)->draw(planner.plan(crowd, cam, 0.0f, taps == 0 ? RenderMode::kGeometry : RenderMode::kImpostor), {});
    const auto px = (*target)->read_rgba();
    if (taps == 0) {
      geometry = px;
      continue;
    }
    const EdgeCounts e = count_edges(px, 182);
    double area = 0, area_g = 0;
    for (std::size_t i = 3; i < px.size(); i += 4) {
      area += px[i] / 255.0;
      area_g += geometry[i] / 255.0;
    }
    int covered = 0;
    psnr[taps] = covered_psnr(Image{128, 128, geometry, {}, 0}, Image{128, 128, px, {}, 0}, &covered);
    std::printf("%d taps: %d opaque, %d partial, area %.1f (geometry %.1f), PSNR %.2f dB\n", taps, e.opaque, e.partial,
                area, area_g, psnr[taps]);
    EXPECT_EQ(e.opaque_off, 0) << taps;
    EXPECT_EQ(e.fringe, 0) << taps;
    EXPECT_EQ(e.not_premultiplied, 0) << taps;
    EXPECT_GT(e.partial, 100) << taps;
    EXPECT_NEAR(area, area_g, 0.02 * area_g) << taps;
  }
  EXPECT_GT(psnr[2], psnr[1] + 0.3);  // measured 26.96 / 27.54 / 27.90 dB (one, two, four) on llvmpipe
  EXPECT_GT(psnr[4], psnr[1] + 0.3);
  EXPECT_GT(psnr[2], psnr[4] - 1.5);
}

// Blended impostors go back to front whatever the crowd's order: the near square's soft edge over
// the far square comes out the same with either character first.
TEST(ImpostorEdges, BlendingIsBackToFront) {
  REQUIRE_GL();
  Model m = square_model();
  SquareScene scene(m, ImpostorConfig{}, 40.0f);
  ASSERT_TRUE(scene.ok());
  const Character near_one{glm::vec3(0.4f, 0.0f, 1.0f)}, far_one{};
  auto frame = [&](const Character& first, const Character& second) {
    FrameStats stats;
    auto px = scene.frame_of({first, second}, RenderMode::kImpostor, &stats);
    EXPECT_EQ(stats.impostors, 2);
    return px;
  };
  const auto a = frame(near_one, far_one), b = frame(far_one, near_one);
  int differ = 0, overlap = 0;
  for (std::size_t i = 0; i < a.size(); i += 4) {
    for (int k = 0; k < 4; ++k) differ += std::abs(a[i + k] - b[i + k]) > 2;
    // The near square's edge over the far one: partly the near grey, fully covered.
    overlap += a[i + 3] >= 250;
  }
  EXPECT_GT(overlap, 1000);
  EXPECT_EQ(differ, 0);
}

// Blended impostors are rasterized single-sampled, so a frame of them alone is the same in a
// single-sampled target as in a multisampled one (impostor_target_samples says 1 for kBlend only):
// two squares whose soft edges overlap, to the byte.
TEST(ImpostorEdges, BlendedImpostorsAloneNeedNoMultisampledTarget) {
  REQUIRE_GL();
  EXPECT_EQ(impostor_target_samples(ImpostorEdges::kBlend, 4), 1);
  EXPECT_EQ(impostor_target_samples(ImpostorEdges::kSamples, 4), 4);
  EXPECT_EQ(impostor_target_samples(ImpostorEdges::kAlphaToCoverage, 8), 8);
  EXPECT_EQ(impostor_target_samples(ImpostorEdges::kAlphaTest, 4), 4);
  EXPECT_EQ(impostor_target_samples(ImpostorEdges::kCentre, 0), 1);
  Model m = square_model();
  ImpostorConfig cfg;
  auto renderer = Renderer::create(m, cfg);
  ASSERT_TRUE(renderer.ok()) << renderer.error().message();
  const SceneCamera cam = square_camera(m, 40.0f);
  Crowd crowd(m);
  crowd.add(Character{glm::vec3(0.4f, 0.0f, 1.0f)});
  crowd.add(Character{});
  auto frame = [&](int samples, int* given) {
    auto target = OffscreenTarget::create(128, 128, samples);
    EXPECT_TRUE(target.ok());
    *given = (*target)->samples();
    FramePlanner planner(m, cfg);  // fresh snapshots for each target
    (*target)->bind(true);
    (*renderer)->draw(planner.plan(crowd, cam, 0.0f, RenderMode::kImpostor));
    return (*target)->read_rgba();
  };
  int ms = 0, ss = 0;
  const auto multi = frame(4, &ms);
  const auto single = frame(impostor_target_samples(ImpostorEdges::kBlend, 4), &ss);
  EXPECT_GE(ms, 4);  // the driver may give more than asked, never fewer
  EXPECT_EQ(ss, 1);
  int partial = 0;
  for (std::size_t i = 3; i < multi.size(); i += 4) partial += multi[i] > 0 && multi[i] < 255;
  EXPECT_GT(partial, 100);  // soft edges, some over the other square
  EXPECT_EQ(single, multi);
}

// The crowd of CrowdRender in a 4x multisampled target, as the flow test bed draws it.
TEST(CrowdRender, MultisampledImpostorFramesMatchGeometryFrames) {
  REQUIRE_GL();
  LOAD_CESIUM_MAN(m);
  Crowd crowd = walker_ring(*m);
  const ImpostorConfig cfg = refresh_always();
  FramePlanner planner(*m, cfg);
  auto renderer = Renderer::create(*m, cfg);
  ASSERT_TRUE(renderer.ok()) << renderer.error().message();
  auto target = OffscreenTarget::create(640, 512, 4);
  ASSERT_TRUE(target.ok());
  const SceneCamera cam = ring_camera();
  for (int f = 0; f < 2; ++f) {
    float t = 0.1f * f;
    (*target)->bind(true);
    const FramePlan& g = planner.plan(crowd, cam, t, RenderMode::kGeometry);
    (*renderer)->draw(g);
    Image gi{640, 512, (*target)->read_rgba(), g.stats, 0};
    const std::size_t geometry_triangles = g.stats.geometry_triangles;
    (*target)->bind(true);
    const FramePlan& p = planner.plan(crowd, cam, t, RenderMode::kImpostor);
    EXPECT_EQ(p.stats.snapshots, 20);
    EXPECT_EQ(p.stats.snapshot_triangles, geometry_triangles);  // the same LODs as the geometry frame
    (*renderer)->draw(p);
    Image ii{640, 512, (*target)->read_rgba(), p.stats, 0};
    int covered = 0;
    double psnr = covered_psnr(gi, ii, &covered);
    std::printf("multisampled crowd frame %d: %d covered pixels, PSNR %.2f dB\n", f, covered, psnr);
    EXPECT_GT(covered, 5000);
    // Measured ~23 dB on llvmpipe (CesiumMan ~40 px tall: edges dominate).
    EXPECT_GT(psnr, 20.0);
  }
}

// Relit snapshots (ImpostorConfig::relight) store albedo and normals and are lit as drawn: with
// the light unchanged they agree with geometry as well as baked snapshots do, and after the light
// moves they follow it without a new snapshot, where baked snapshots keep the old light.
TEST(CrowdRender, RelitImpostorsFollowTheLightWithoutNewSnapshots) {
  REQUIRE_GL();
  LOAD_CESIUM_MAN(m);
  Crowd crowd = walker_ring(*m);
  const SceneCamera cam = ring_camera();
  const glm::vec3 moved(-0.8f, 0.3f, -0.5f);
  // PSNR against geometry of the impostors drawn under the first light, then of the same
  // snapshots drawn again (none taken) after the light moved.
  auto run = [&](bool relight) {
    ImpostorConfig cfg = refresh_always();
    cfg.relight = relight;
    FramePlanner planner(*m, cfg);
    auto renderer = Renderer::create(*m, cfg);
    EXPECT_TRUE(renderer.ok()) << renderer.error().message();
    auto target = OffscreenTarget::create(640, 512, 4);
    EXPECT_TRUE(target.ok());
    if (!renderer.ok() || !target.ok()) return std::pair{0.0, 0.0};
    auto geometry = [&] {
      (*target)->bind(true);
      const FramePlan& g = planner.plan(crowd, cam, 0.3f, RenderMode::kGeometry);
      (*renderer)->draw(g);
      return Image{640, 512, (*target)->read_rgba(), g.stats, 0};
    };
    const Image g0 = geometry();
    (*target)->bind(true);
    const FramePlan p = planner.plan(crowd, cam, 0.3f, RenderMode::kImpostor);  // a copy
    EXPECT_EQ(p.stats.snapshots, 20);
    (*renderer)->draw(p);
    const Image i0{640, 512, (*target)->read_rgba(), p.stats, 0};
    (*renderer)->set_light(moved);
    const Image g1 = geometry();
    (*target)->bind(true);
    DrawOptions again;
    again.take_snapshots = false;
    (*renderer)->draw(p, again);
    const Image i1{640, 512, (*target)->read_rgba(), p.stats, 0};
    int covered = 0;
    const double before = covered_psnr(g0, i0, &covered);
    EXPECT_GT(covered, 5000);
    const double after = covered_psnr(g1, i1, &covered);
    std::printf("%s snapshots: %.2f dB under the first light, %.2f dB after it moved (no new snapshot)\n",
                relight ? "relit" : "baked", before, after);
    return std::pair{before, after};
  };
  const auto [baked0, baked1] = run(false);
  const auto [relit0, relit1] = run(true);
  // Measured on llvmpipe: baked 24.98 -> 11.08 dB, relit 24.94 -> 27.23 dB.
  EXPECT_NEAR(relit0, baked0, 0.5);
  EXPECT_LT(baked1, baked0 - 3.0);
  EXPECT_GT(relit1, baked1 + 3.0);
  EXPECT_GT(relit1, relit0 - 1.0);
}

// Quads fitted to the coverage: the GPU's rectangle holds every covered texel of the window, is
// smaller than the planner's box-made quad, and drawing with it gives the same frame (to one level).
// The coverage pass's work groups of 4x4 (llvmpipe's), 8x8 and 16x16 (a GPU's) invocations find
// the same rectangles: the same checks hold and the frames are the same to the bit.
TEST(CrowdRender, QuadsFittedToTheCoverageHoldEveryCoveredTexel) {
  REQUIRE_GL();
  LOAD_CESIUM_MAN(m);
  Crowd crowd = walker_ring(*m);
  // One frame with every impostor refreshed; with fitted quads, also checks each rectangle.
  // Depth-corrected part cards: the rectangles come from the plane offsets' mask, in the pass that
  // also writes their wide texels.
  auto frame = [&](float tpp, bool fit, bool depth_cards = false, int group = 4, int taps = 4) {
    ImpostorConfig cfg = refresh_always();
    cfg.texels_per_pixel = tpp;
    cfg.impostor_taps = taps;
    cfg.fit_quads_to_coverage = fit;
    cfg.coverage_group = group;
    cfg.part_cards = cfg.parallax_cards = depth_cards;
    FramePlanner planner(*m, cfg);
    auto renderer = Renderer::create(*m, cfg);
    EXPECT_TRUE(renderer.ok()) << renderer.error().message();
    auto target = OffscreenTarget::create(640, 512, 4);
    EXPECT_TRUE(target.ok());
    if (!renderer.ok() || !target.ok()) return std::vector<std::uint8_t>{};
    EXPECT_EQ((*renderer)->coverage_group(), group);
    (*target)->bind(true);
    const FramePlan& p = planner.plan(crowd, ring_camera(), 0.3f, RenderMode::kImpostor);
    DrawOptions blend;
    blend.edges = ImpostorEdges::kBlend;
    (*renderer)->draw(p, blend);
    std::vector<std::uint8_t> image = (*target)->read_rgba();
    if (!fit) return image;
    std::map<int, std::vector<std::uint8_t>> pages;  // read once each
    double planned = 0, fitted = 0, fitted_texels = 0;
    for (const BillboardGpu& b : p.billboards) {
      EXPECT_GT(b.layer.z, 0.5f);
      auto [it, fresh] = pages.try_emplace(static_cast<int>(b.layer.x));
      if (fresh) it->second = (*renderer)->read_atlas_page(it->first);
      const glm::vec4 r = (*renderer)->coverage_rect(static_cast<int>(b.layer.y));
      EXPECT_LT(r.x, r.z);
      const WindowCoverage w = window_coverage(it->second, cfg.page_size, b, r);
      const int size = w.size;
      EXPECT_GT(w.covered, size * size / 25);  // a picture, not an empty window (a small part fills little of its 32)
      EXPECT_EQ(w.outside, 0);
      // And no larger: the covered texels' bounds widened by the same margin (the taps' reach, a
      // few texels) on every side.
      const float(&margin)[4] = w.margin;
      for (float mk : margin) {
        EXPECT_NEAR(mk, margin[0], 1e-3f);
        EXPECT_GE(mk, 0.0f);
        EXPECT_LE(mk, depth_cards ? 8.0f : 4.0f);  // small parts' windows: more texels per pixel, more reach
      }
      const glm::vec4 q(glm::max(glm::vec2(r), glm::vec2(b.rect)), glm::min(glm::vec2(r.z, r.w), glm::vec2(b.rect.z, b.rect.w)));
      planned += (b.rect.z - b.rect.x) * (b.rect.w - b.rect.y);
      fitted += (q.z - q.x) * (q.w - q.y);
      fitted_texels += (q.z - q.x) * (q.w - q.y) * 0.25 * size * size;
    }
    std::printf("fitted quads, %g texels per pixel, %d taps%s: %.0f %% of the planner's quads' area\n", tpp, taps,
                depth_cards ? ", depth-corrected part cards" : "", 100.0 * fitted / planned);
    EXPECT_LT(fitted, 0.97 * planned);  // measured 91-92 % (CesiumMan ~40 px tall; 2-4-texel margins)
    // The report's figure: the same quads, in texels.
    EXPECT_NEAR((*renderer)->drawn_quad_texels(p), fitted_texels, 1e-4 * fitted_texels);
    return image;
  };
  // The runtime's default (2 texels per pixel, 4 taps) and the flow test bed's (1 texel per pixel:
  // 4 taps for part cards, 1 for whole impostors on the pixel grid; 2 on a GPU): the quads'
  // margin is the reach of those taps (taps_reach), so each must keep every pixel that shows
  // coverage.
  for (auto [tpp, taps] : {std::pair{1.0f, 4}, std::pair{2.0f, 4}, std::pair{1.0f, 1}, std::pair{1.0f, 2}, std::pair{2.0f, 2}}) {
    const auto boxes = frame(tpp, false, false, 4, taps), fitted = frame(tpp, true, false, 4, taps);
    ASSERT_EQ(boxes.size(), fitted.size());
    // Only pixels without coverage are left out: the same frame, but for the rounding of texture
    // coordinates interpolated over a smaller quad.
    int differ = 0, worst = 0;
    for (std::size_t i = 0; i < boxes.size(); ++i) {
      const int d = std::abs(int(boxes[i]) - int(fitted[i]));
      differ += d > 0;
      worst = std::max(worst, d);
    }
    std::printf("fitted quads: %d channel values differ, by at most %d\n", differ, worst);
    EXPECT_LE(worst, 1);
    for (int group : {8, 16}) EXPECT_EQ(frame(tpp, true, false, group, taps), fitted) << group << "x" << group << " work groups";
  }
  const auto depth4 = frame(1.0f, true, true);
  EXPECT_EQ(frame(1.0f, true, true, 16), depth4) << "16x16 work groups, depth-corrected part cards";
}

// ImpostorConfig::fit_quads_from_vertices: quads fitted on the CPU from the snapshot level's
// skinned vertices (whole impostors, part cards) hold every texel the snapshot covers (read back
// from the atlas), are little larger than the coverage pass's, and give the same frame without
// the pass.
TEST(CrowdRender, QuadsFittedFromTheVerticesHoldEveryCoveredTexel) {
  REQUIRE_GL();
  LOAD_CESIUM_MAN(m);
  Crowd crowd = walker_ring(*m);
  for (auto [tpp, cards] : {std::pair{1.0f, false}, std::pair{2.0f, false}, std::pair{1.0f, true}}) {
    std::vector<std::uint8_t> images[2];
    double area[2] = {0, 0};
    for (int from_vertices = 0; from_vertices < 2; ++from_vertices) {
      ImpostorConfig cfg = refresh_always();
      cfg.texels_per_pixel = tpp;
      cfg.part_cards = cards;
      cfg.fit_quads_from_vertices = from_vertices == 1;
      FramePlanner planner(*m, cfg);
      auto renderer = Renderer::create(*m, cfg);
      ASSERT_TRUE(renderer.ok()) << renderer.error().message();
      auto target = OffscreenTarget::create(640, 512, 4);
      ASSERT_TRUE(target.ok());
      (*target)->bind(true);
      const FramePlan& p = planner.plan(crowd, ring_camera(), 0.3f, RenderMode::kImpostor);
      ASSERT_FALSE(p.billboards.empty());
      DrawOptions blend;
      blend.edges = ImpostorEdges::kBlend;
      (*renderer)->draw(p, blend);
      images[from_vertices] = (*target)->read_rgba();
      std::map<int, std::vector<std::uint8_t>> pages;
      for (const BillboardGpu& b : p.billboards) {
        glm::vec4 r = b.rect;
        if (from_vertices == 0) {
          ASSERT_GT(b.layer.z, 0.5f);  // fitted by the pass
          const glm::vec4 f = (*renderer)->coverage_rect(static_cast<int>(b.layer.y));
          r = glm::vec4(glm::max(glm::vec2(r), glm::vec2(f)), glm::min(glm::vec2(r.z, r.w), glm::vec2(f.z, f.w)));
        } else {
          ASSERT_LT(b.layer.z, 0.5f);  // fitted already: no pass
        }
        area[from_vertices] += (r.z - r.x) * (r.w - r.y);
        if (from_vertices == 0) continue;
        auto [it, fresh] = pages.try_emplace(static_cast<int>(b.layer.x));
        if (fresh) it->second = (*renderer)->read_atlas_page(it->first);
        const WindowCoverage w = window_coverage(it->second, cfg.page_size, b, r);
        EXPECT_GT(w.covered, w.size * w.size / 25);
        EXPECT_EQ(w.outside, 0);
        // The taps' reach (2 to 3 texels here) and up to a texel and a half where the vertices lie
        // past the covered texels' centres (more past thin triangles), on every side.
        for (float mk : w.margin) {
          EXPECT_GE(mk, cards ? 0.0f : 1.0f);  // a part's box (the planner's quad) may cut it
          EXPECT_LE(mk, cards ? 8.0f : 5.0f);  // cards: more texels per pixel, thin triangles
        }
      }
    }
    std::printf("quads from the vertices, %g texels per pixel%s: %.1f %% of the coverage pass's area\n", tpp,
                cards ? ", part cards" : "", 100.0 * area[1] / area[0]);
    EXPECT_GE(area[1], area[0]);
    EXPECT_LT(area[1], 1.25 * area[0]);
    ASSERT_EQ(images[0].size(), images[1].size());
    // Whole impostors: the same frame but for the rounding of texture coordinates interpolated over
    // another quad. Part cards: also a few edge pixels that the pass's tighter rectangle cut (its
    // margin is the taps' reach exactly) and the vertices' keeps, so never less coverage.
    int worst = 0, differ = 0, less = 0;
    for (std::size_t i = 0; i < images[0].size(); ++i) {
      const int d = int(images[1][i]) - int(images[0][i]);
      worst = std::max(worst, std::abs(d));
      differ += std::abs(d) > 1;
      less += i % 4 == 3 && d < -1;
    }
    std::printf("  %d channel values differ by more than 1, by at most %d\n", differ, worst);
    EXPECT_EQ(less, 0);
    if (cards)
      EXPECT_LE(differ, 64);  // measured 14 (4 pixels)
    else
      EXPECT_LE(worst, 1);
  }
}

// Snapshots on the pixel grid, multisampled like the scene and blended: a fresh impostor is the
// geometry's own picture (texels copied onto the pixels, coverage resolved the same way), so the
// frames agree to rounding where the free snapshot camera resamples (~23 dB above).
TEST(CrowdRender, AlignedMultisampledSnapshotsCopyTheGeometry) {
  REQUIRE_GL();
  LOAD_CESIUM_MAN(m);
  Crowd crowd = walker_ring(*m);
  ImpostorConfig cfg = refresh_always();
  cfg.aligned_snapshots = true;
  cfg.snapshot_samples = 4;
  cfg.texels_per_pixel = 1.0f;
  FramePlanner planner(*m, cfg);
  auto renderer = Renderer::create(*m, cfg);
  ASSERT_TRUE(renderer.ok()) << renderer.error().message();
  auto target = OffscreenTarget::create(640, 512, 4);
  ASSERT_TRUE(target.ok());
  const SceneCamera cam = ring_camera();
  DrawOptions blend;
  blend.edges = ImpostorEdges::kBlend;
  for (int f = 0; f < 2; ++f) {
    float t = 0.1f * f;
    (*target)->bind(true);
    const FramePlan& g = planner.plan(crowd, cam, t, RenderMode::kGeometry);
    (*renderer)->draw(g, blend);
    Image gi{640, 512, (*target)->read_rgba(), g.stats, 0};
    (*target)->bind(true);
    const FramePlan& p = planner.plan(crowd, cam, t, RenderMode::kImpostor);
    EXPECT_EQ(p.stats.snapshots, 20);
    (*renderer)->draw(p, blend);
    Image ii{640, 512, (*target)->read_rgba(), p.stats, 0};
    int covered = 0;
    double psnr = covered_psnr(gi, ii, &covered);
    std::printf("aligned multisampled crowd frame %d: %d covered pixels, PSNR %.2f dB\n", f, covered, psnr);
    EXPECT_GT(covered, 5000);
    EXPECT_GT(psnr, 40.0);
    if (f == 1) save_ppm_pair(std::string(BB_BIN_DIR) + "/../crowd_aligned_CesiumMan.ppm", gi, ii);
  }
}

// Depth-corrected part cards (ImpostorConfig::parallax_cards): snapshots taken from one camera,
// then, the poses held, the camera turned 6 degrees about the crowd (view threshold 30: cards
// are refreshed only where their window size changes). Each pixel then looks up the texel whose stored surface lies on its own ray, so
// the cards agree with the geometry better than flat cards do.
TEST(CrowdRender, DepthCorrectedCardsFollowTheParallax) {
  REQUIRE_GL();
  LOAD_CESIUM_MAN(m);
  ASSERT_GT(m->body_parts().size(), 1u);
  Crowd crowd = walker_ring(*m);
  const SceneCamera a = ring_camera();
  SceneCamera b = a;
  const float turn = glm::radians(6.0f);
  const glm::vec3 d = a.eye - a.target;
  b.eye = a.target + glm::vec3(std::cos(turn) * d.x + std::sin(turn) * d.z, d.y, -std::sin(turn) * d.x + std::cos(turn) * d.z);
  DrawOptions blend;
  blend.edges = ImpostorEdges::kBlend;
  auto psnr_after_turn = [&](bool parallax, bool depth_pass = false) {
    ImpostorConfig cfg;
    cfg.part_cards = true;
    cfg.parallax_cards = parallax;
    cfg.parallax_depth_pass = depth_pass;
    cfg.lead_cards = false;  // the poses are held: a look-ahead along the clip would mislead
    cfg.cache.posture_test = false;
    cfg.cache.view_threshold_deg = 30.0f;
    FramePlanner planner(*m, cfg);
    auto renderer = Renderer::create(*m, cfg);
    EXPECT_TRUE(renderer.ok()) << renderer.error().message();
    auto target = OffscreenTarget::create(640, 512, 4);
    EXPECT_TRUE(target.ok());
    if (!renderer.ok() || !target.ok()) return 0.0;
    const float t = 0.3f;
    (*target)->bind(true);
    (*renderer)->draw(planner.plan(crowd, a, t, RenderMode::kImpostor), blend);  // the snapshots
    (*target)->bind(true);
    const FramePlan& g = planner.plan(crowd, b, t, RenderMode::kGeometry);
    (*renderer)->draw(g);
    Image gi{640, 512, (*target)->read_rgba(), g.stats, 0};
    (*target)->bind(true);
    const FramePlan& p = planner.plan(crowd, b, t, RenderMode::kImpostor);
    // Cards drawn from the first camera's snapshots (a few change window size).
    EXPECT_GT(p.stats.part_cards, 100);
    EXPECT_LE(p.stats.part_snapshots * 20, p.stats.part_cards);
    (*renderer)->draw(p, blend);
    Image ii{640, 512, (*target)->read_rgba(), p.stats, 0};
    int covered = 0;
    const double psnr = covered_psnr(gi, ii, &covered);
    std::printf("part cards %s, camera turned 6 degrees: %d covered pixels, PSNR %.2f dB\n",
                parallax ? (depth_pass ? "depth-corrected, depth pass" : "depth-corrected") : "flat", covered, psnr);
    EXPECT_GT(covered, 5000);
    if (parallax) save_ppm_pair(std::string(BB_BIN_DIR) + "/../parallax_cards_CesiumMan.ppm", gi, ii);
    return psnr;
  };
  const double flat = psnr_after_turn(false), corrected = psnr_after_turn(true);
  EXPECT_GT(corrected, flat + 1.0);  // measured on llvmpipe: 20.85 -> 22.70 dB
  // With the depth pass the cards overlapping at the joints are ordered per pixel.
  const double ordered = psnr_after_turn(true, true);
  EXPECT_GT(ordered, corrected);  // 22.70 -> 22.85 dB
}


// The frames of both paths of a SquareScene of `m` (none where it could not be made).
std::map<RenderMode, std::vector<std::uint8_t>> square_frames(const Model& m, const ImpostorConfig& cfg = SquareScene::fresh()) {
  std::map<RenderMode, std::vector<std::uint8_t>> frames;
  SquareScene scene(m, cfg);
  if (!scene.ok()) return frames;
  for (RenderMode mode : {RenderMode::kGeometry, RenderMode::kImpostor}) frames[mode] = scene.frame(mode);
  return frames;
}

// Vertex colours (COLOR_0) multiply the base colour in both paths: an orange square (255, 128, 0) lit
// as the plain white one is, channel by channel, in the geometry frame and in the impostor's.
TEST(CrowdRender, VertexColoursMultiplyTheBaseColour) {
  REQUIRE_GL();
  const Model plain = square_model();
  Model colored = square_model();
  for (Vertex& v : colored.lods[0].vertices) v.color = {255, 128, 0, 255};
  colored.materials[0].vertex_colors = true;
  auto white_frames = square_frames(plain), orange_frames = square_frames(colored);
  ASSERT_EQ(white_frames.size(), 2u);
  ASSERT_EQ(orange_frames.size(), 2u);
  for (RenderMode mode : {RenderMode::kGeometry, RenderMode::kImpostor}) {
    const char* path = mode == RenderMode::kGeometry ? " geometry" : " impostor";
    const auto& white = white_frames[mode];
    const auto& orange = orange_frames[mode];
    int opaque = 0, matched = 0;
    for (std::size_t i = 0; i < white.size(); i += 4) {
      if (white[i + 3] < 255 || orange[i + 3] < 255) continue;
      ++opaque;
      const int lit = white[i];  // the plain square's grey: its lighting
      matched += orange[i] == lit && std::abs(orange[i + 1] - lit * 128 / 255) <= 1 && orange[i + 2] == 0;
    }
    std::printf("vertex colours%s: %d opaque pixels, %d of them the white square's lighting times (255, 128, 0)\n",
                path, opaque, matched);
    EXPECT_GT(opaque, 2000) << path;
    EXPECT_EQ(matched, opaque) << path;
  }
}

// Back faces of a single-sided material (glTF's default) are culled in both paths: the square wound
// clockwise as seen from the camera covers no pixel, as geometry and as an impostor (its snapshot culls
// them too); double-sided, it covers as many pixels as the square wound the right way.
TEST(CrowdRender, SingleSidedMaterialsHideTheirBackFaces) {
  REQUIRE_GL();
  auto covered = [](const std::vector<std::uint8_t>& px) {
    int n = 0;
    for (std::size_t i = 3; i < px.size(); i += 4) n += px[i] > 0;
    return n;
  };
  const Model front = square_model();
  Model back = square_model();
  back.lods[0].indices = {0, 2, 1, 0, 3, 2};
  Model both = back;
  both.materials[0].double_sided = true;
  auto f = square_frames(front), b = square_frames(back), d = square_frames(both);
  ASSERT_EQ(f.size(), 2u);
  ASSERT_EQ(b.size(), 2u);
  ASSERT_EQ(d.size(), 2u);
  for (RenderMode mode : {RenderMode::kGeometry, RenderMode::kImpostor}) {
    const char* path = mode == RenderMode::kGeometry ? "geometry" : "impostor";
    const int nf = covered(f[mode]), nb = covered(b[mode]), nd = covered(d[mode]);
    std::printf("%s: front faces %d pixels, back faces single-sided %d, double-sided %d\n", path, nf, nb, nd);
    EXPECT_GT(nf, 2000) << path;
    EXPECT_EQ(nb, 0) << path;
    EXPECT_EQ(nd, nf) << path;
  }
}

// Part cards close their cuts (PartIndices::Range::caps): the square tube of two parts
// (tube_model.h) seen from the side, its cards taken bent 30 degrees, then carried by their bones to
// 60 degrees without a refresh. The top card has turned away from the bottom part's cut, which the
// bottom part's cap closes; without caps its culled snapshot showed the background through the cut
// there, a band across the tube. Measured on llvmpipe: 270 of 12,986 pixels that the geometry covers
// whole are uncovered by the cards with caps (the skin stretched further than the cards can follow),
// 992 without.
TEST(CrowdRender, PartCardsCloseTheirCuts) {
  REQUIRE_GL();
  const Model m = tube_model(60.0f);
  ASSERT_EQ(m.body_parts().size(), 2u);
  ImpostorConfig cfg;
  cfg.part_cards = true;
  cfg.lead_cards = false;
  cfg.cache.posture_test = false;
  cfg.cache.view_test = false;
  Crowd crowd(m);
  crowd.add(Character{});
  FramePlanner planner(m, cfg);
  auto renderer = Renderer::create(m, cfg);
  ASSERT_TRUE(renderer.ok()) << renderer.error().message();
  auto target = OffscreenTarget::create(256, 256, 4);
  ASSERT_TRUE(target.ok());
  SceneCamera cam;
  cam.width = cam.height = 256;
  cam.target = glm::vec3(0.0f, 1.2f, 0.0f);
  cam.eye = glm::vec3(-6.0f, 4.0f, 0.0f);
  DrawOptions blend;
  blend.edges = ImpostorEdges::kBlend;
  (*target)->bind(true);
  const FramePlan& first = planner.plan(crowd, cam, 0.5f, RenderMode::kImpostor);  // bent 30 degrees
  EXPECT_EQ(first.stats.part_snapshots, 2);
  (*renderer)->draw(first, blend);
  std::map<RenderMode, std::vector<std::uint8_t>> px;
  for (RenderMode mode : {RenderMode::kGeometry, RenderMode::kImpostor}) {  // bent 60 degrees
    (*target)->bind(true);
    const FramePlan& plan = planner.plan(crowd, cam, 1.0f, mode);
    if (mode == RenderMode::kImpostor) {
      EXPECT_EQ(plan.stats.part_snapshots, 0);  // the cards carried by their bones
    }
    (*renderer)->draw(plan, blend);
    px[mode] = (*target)->read_rgba();
  }
  int covered = 0, holes = 0;
  for (std::size_t i = 3; i < px[RenderMode::kGeometry].size(); i += 4) {
    covered += px[RenderMode::kGeometry][i] == 255;
    holes += px[RenderMode::kGeometry][i] == 255 && px[RenderMode::kImpostor][i] == 0;
  }
  save_ppm_pair(std::string(BB_BIN_DIR) + "/../tube_cards.ppm", Image{256, 256, px[RenderMode::kGeometry], {}, 0},
                Image{256, 256, px[RenderMode::kImpostor], {}, 0});
  std::printf("bent tube: %d pixels covered whole by the geometry, %d of them uncovered by the part cards\n", covered, holes);
  EXPECT_GT(covered, 10000);
  EXPECT_LT(holes, covered / 25);
}

// Impostor quads pulled by the vertex shader from a buffer texture (ImpostorConfig::quad_fetch 2,
// the default on a software rasterizer) draw the pixels that instanced quads (1) draw, byte for byte:
// whole impostors, depth-corrected part cards (with their depth pass: two draws of one range), relit
// part cards (their frame from the carried axes), and
// two models' quads through draw_many, both with an atlas each (a draw per model and layer, from an
// offset into each model's quads) and with one shared atlas (one draw).
TEST(CrowdRender, PulledQuadsDrawWhatInstancedQuadsDraw) {
  REQUIRE_GL();
  const Model m = tube_model(60.0f);
  Crowd crowd(m), even(m), odd(m);
  for (int i = 0; i < 12; ++i) {
    Character c;
    c.position = glm::vec3(0.9f * (i % 4) - 1.35f, 0.0f, -1.1f * (i / 4));  // overlapping on screen
    c.yaw = 0.5f * i;
    c.phase = 0.07f * i;
    crowd.add(c);
    (i % 2 ? odd : even).add(c);
  }
  SceneCamera cam;
  cam.width = 320;
  cam.height = 256;
  cam.target = glm::vec3(0.0f, 1.0f, -1.0f);
  cam.eye = glm::vec3(0.5f, 3.0f, 6.0f);
  DrawOptions blend;
  blend.edges = ImpostorEdges::kBlend;
  auto target = OffscreenTarget::create(cam.width, cam.height, 4);
  ASSERT_TRUE(target.ok());
  // Two frames (the second from a turned camera, some snapshots kept) of `crowd` drawn by one renderer.
  auto frames = [&](ImpostorConfig cfg, int fetch) {
    cfg.quad_fetch = fetch;
    FramePlanner planner(m, cfg);
    auto renderer = Renderer::create(m, cfg);
    EXPECT_TRUE(renderer.ok()) << renderer.error().message();
    std::vector<std::uint8_t> px;
    if (!renderer.ok()) return px;
    EXPECT_EQ((*renderer)->pulls_quads(), fetch == 2);
    SceneCamera c = cam;
    for (int f = 0; f < 2; ++f) {
      c.eye.x += 0.4f * f;
      (*target)->bind(true);
      (*renderer)->draw(planner.plan(crowd, c, 0.3f + 0.1f * f, RenderMode::kImpostor), blend);
      const std::vector<std::uint8_t> frame = (*target)->read_rgba();
      px.insert(px.end(), frame.begin(), frame.end());
    }
    return px;
  };
  // The same two frames of `even` and `odd` through draw_many, with an atlas each or one shared.
  auto many_frames = [&](ImpostorConfig cfg, int fetch, bool shared) {
    cfg.quad_fetch = fetch;
    cfg.max_pages = 4;
    const ImpostorConfig c0 = shared ? shared_atlas_config(cfg, 0, 2) : cfg, c1 = shared ? shared_atlas_config(cfg, 1, 2) : cfg;
    FramePlanner p0(m, c0), p1(m, c1);
    auto r0 = Renderer::create(m, c0);
    EXPECT_TRUE(r0.ok());
    std::vector<std::uint8_t> px;
    if (!r0.ok()) return px;
    auto r1 = Renderer::create(m, c1, shared ? r0->get() : nullptr);
    EXPECT_TRUE(r1.ok());
    if (!r1.ok()) return px;
    SceneCamera c = cam;
    for (int f = 0; f < 2; ++f) {
      c.eye.x += 0.4f * f;
      (*target)->bind(true);
      const FramePlan* ps[2] = {&p0.plan(even, c, 0.3f + 0.1f * f, RenderMode::kImpostor),
                                &p1.plan(odd, c, 0.3f + 0.1f * f, RenderMode::kImpostor)};
      Renderer* rs[2] = {r0->get(), r1->get()};
      Renderer::draw_many(rs, ps, blend);
      const std::vector<std::uint8_t> frame = (*target)->read_rgba();
      px.insert(px.end(), frame.begin(), frame.end());
    }
    return px;
  };
  auto compare = [](const char* what, const std::vector<std::uint8_t>& instanced, const std::vector<std::uint8_t>& pulled) {
    ASSERT_EQ(instanced.size(), pulled.size()) << what;
    int covered = 0, differ = 0;
    for (std::size_t i = 0; i < pulled.size(); ++i) differ += instanced[i] != pulled[i];
    for (std::size_t i = 3; i < pulled.size(); i += 4) covered += pulled[i] > 0;
    std::printf("%s: %d covered pixels in two frames, %d bytes differ between instanced and pulled quads\n", what, covered,
                differ);
    EXPECT_GT(covered, 4000) << what;
    EXPECT_EQ(differ, 0) << what;
  };
  ImpostorConfig whole;
  whole.cache.posture_test = false;
  whole.cache.view_threshold_deg = 5.0f;
  compare("whole impostors", frames(whole, 1), frames(whole, 2));
  ImpostorConfig cards = whole;
  cards.part_cards = true;
  cards.parallax_cards = true;
  cards.parallax_depth_pass = true;
  compare("depth-corrected part cards", frames(cards, 1), frames(cards, 2));
  ImpostorConfig relit = whole;
  relit.part_cards = true;
  relit.relight = true;
  compare("relit part cards", frames(relit, 1), frames(relit, 2));
  compare("two models, an atlas each", many_frames(whole, 1, false), many_frames(whole, 2, false));
  compare("two models, one atlas", many_frames(whole, 1, true), many_frames(whole, 2, true));
}

// An unlit material (KHR_materials_unlit) is drawn in its base colour, (0.4, 0.2, 0.8) -> (102, 51, 204),
// in both paths, with baked and with relit snapshots; a relit one stays so after the light moves. The
// same square lit has other colours (white lit: 182, see ImpostorEdges).
TEST(CrowdRender, UnlitMaterialsKeepTheirColour) {
  REQUIRE_GL();
  Model m = square_model();
  m.materials[0].base_color = glm::vec4(0.4f, 0.2f, 0.8f, 1.0f);
  const int want[3] = {102, 51, 204};
  auto count = [&](const std::vector<std::uint8_t>& px) {
    std::pair<int, int> opaque_exact{0, 0};
    for (std::size_t i = 0; i < px.size(); i += 4) {
      if (px[i + 3] < 255) continue;
      ++opaque_exact.first;
      bool exact = true;
      for (int k = 0; k < 3; ++k) exact = exact && std::abs(px[i + k] - want[k]) <= 1;
      opaque_exact.second += exact;
    }
    return opaque_exact;
  };
  for (bool unlit : {false, true}) {
    m.materials[0].unlit = unlit;
    for (bool relight : {false, true}) {
      SquareScene scene(m, SquareScene::fresh(relight));
      ASSERT_TRUE(scene.ok());
      for (RenderMode mode : {RenderMode::kGeometry, RenderMode::kImpostor}) {
        const auto [opaque, exact] = count(scene.frame(mode));
        std::printf("%s, %s snapshots, %s: %d opaque pixels, %d of the base colour\n", unlit ? "unlit" : "lit",
                    relight ? "relit" : "baked", mode == RenderMode::kGeometry ? "geometry" : "impostor", opaque, exact);
        EXPECT_GT(opaque, 2000);
        EXPECT_EQ(exact, unlit ? opaque : 0);
      }
      if (relight) {  // the light moved, the same snapshot drawn again
        scene.renderer->set_light(glm::vec3(-0.8f, 0.3f, -0.5f));
        DrawOptions again;
        again.take_snapshots = false;
        const auto [opaque, exact] = count(scene.frame(RenderMode::kImpostor, again));
        EXPECT_GT(opaque, 2000);
        EXPECT_EQ(exact, unlit ? opaque : 0);
      }
    }
  }
}

// Alpha BLEND in both paths, with baked and relit snapshots, on the square (white, lit to 182) and a
// second one 5 cm behind it (red): the blended square is listed first but drawn over the opaque one,
// without hiding it. Where the squares overlap: half of each, (182, 91, 91), opaque; where the white
// one is alone, its colour at half alpha over the transparent target, premultiplied: (91, 91, 91, 128).
// Drawn first with depth, the white would hide the red, (91, 91, 91, 128) there too; drawn first without
// it, the red would cover it, (182, 0, 0). Alpha-tested as MASK at 0.5 used to: the white opaque.
TEST(CrowdRender, BlendedSurfacesLieOverTheOpaqueOnes) {
  REQUIRE_GL();
  Model m = square_model();
  MeshLod& lod = m.lods[0];
  for (std::uint32_t k = 0; k < 4; ++k) {
    Vertex v = lod.vertices[k];
    v.position = glm::vec3(v.position.x * 1.02f + 0.05f, v.position.y, -0.05f);  // offset: a strip of white alone
    lod.vertices.push_back(v);
  }
  for (std::uint32_t i : {4u, 5u, 6u, 4u, 6u, 7u}) lod.indices.push_back(i);
  lod.primitives = {Primitive{0, 6, 0}, Primitive{6, 6, 1}};
  m.materials = {Material{}, Material{}};
  m.materials[0].base_color = glm::vec4(1.0f, 1.0f, 1.0f, 0.5f);
  m.materials[0].alpha_blend = true;
  m.materials[1].base_color = glm::vec4(1.0f, 0.0f, 0.0f, 1.0f);
  m.bake(30.0f);
  auto near = [](const std::uint8_t* px, std::array<int, 4> want) {
    for (int k = 0; k < 4; ++k)
      if (std::abs(px[k] - want[k]) > 2) return false;
    return true;
  };
  for (bool relight : {false, true}) {
    SquareScene scene(m, SquareScene::fresh(relight));
    ASSERT_TRUE(scene.ok());
    for (RenderMode mode : {RenderMode::kGeometry, RenderMode::kImpostor}) {
      const auto px = scene.frame(mode);
      int both = 0, white_alone = 0, red_alone = 0, other = 0;
      for (std::size_t i = 0; i < px.size(); i += 4) {
        // Whole pixels only, away from the edges (a pixel with some of each has neither colour).
        if (near(&px[i], {182, 91, 91, 255})) ++both;
        else if (near(&px[i], {91, 91, 91, 128})) ++white_alone;
        else if (near(&px[i], {182, 0, 0, 255})) ++red_alone;
        else if (px[i + 3] > 0) ++other;
      }
      std::printf("%s snapshots, %s: %d pixels of both squares, %d of the blended one alone, %d of the opaque one alone, %d others\n",
                  relight ? "relit" : "baked", mode == RenderMode::kGeometry ? "geometry" : "impostor", both, white_alone,
                  red_alone, other);
      EXPECT_GT(both, 2000);
      EXPECT_GT(white_alone, 30);
      EXPECT_GT(red_alone, 30);
      EXPECT_LT(other, both / 4);  // the edges'
    }
  }
}

// Alpha-blended surfaces of different characters lie over each other back to front, whatever the
// crowd's order. Two half-alpha white squares: A facing the camera and light (lit 182), B 1.5 m behind
// it and turned 60 degrees away (lit darker). Where both cover a pixel, the frame must be A over B,
// premultiplied: A + (1 - 0.5) B, from the frames of each alone (within 3 levels), in the geometry
// frame and in the impostors' (sorted quads). B over A differs there by over 20 levels, so a pass in
// the crowd's order fails with A listed first.
TEST(CrowdRender, BlendedSurfacesOfCharactersLieBackToFront) {
  REQUIRE_GL();
  Model m = square_model();
  m.materials[0].base_color = glm::vec4(1.0f, 1.0f, 1.0f, 0.5f);
  m.materials[0].alpha_blend = true;
  m.bake(30.0f);
  SquareScene scene(m);
  ASSERT_TRUE(scene.ok());
  const Character a{}, b{glm::vec3(0.0f, 0.0f, -1.5f), glm::radians(-60.0f)};
  auto frame = [&](const std::vector<Character>& chars, RenderMode mode) { return scene.frame_of(chars, mode); };
  for (RenderMode mode : {RenderMode::kGeometry, RenderMode::kImpostor}) {
    const char* path = mode == RenderMode::kGeometry ? "geometry" : "impostor";
    const auto pa = frame({a}, mode), pb = frame({b}, mode);
    for (bool a_first : {true, false}) {
      const auto both = a_first ? frame({a, b}, mode) : frame({b, a}, mode);
      int overlap = 0, a_over_b = 0, distinct = 0;
      for (std::size_t i = 0; i < both.size(); i += 4) {
        // Whole pixels of both squares (half alpha each), away from their edges.
        if (std::abs(pa[i + 3] - 128) > 2 || std::abs(pb[i + 3] - 128) > 2) continue;
        ++overlap;
        bool ok = std::abs(both[i + 3] - 191) <= 3;
        for (int k = 0; k < 3; ++k) {
          ok = ok && std::abs(both[i + k] - (pa[i + k] + pb[i + k] / 2.0)) <= 3.0;
          distinct += k == 0 && std::abs((pa[i] + pb[i] / 2.0) - (pb[i] + pa[i] / 2.0)) > 20.0;
        }
        a_over_b += ok;
      }
      std::printf("%s, %s listed first: %d pixels of both squares, %d of them A over B, %d where B over A differs\n", path,
                  a_first ? "A" : "B", overlap, a_over_b, distinct);
      EXPECT_GT(overlap, 400) << path;
      EXPECT_EQ(distinct, overlap) << path;
      EXPECT_GE(a_over_b, overlap - overlap / 100) << path << (a_first ? ", A first" : ", B first");
    }
  }
}

// A material's sampler decides how the texture is read outside [0, 1] and when magnified. The square's u
// runs from -1 to 2 across it over a texture of two texels (blue, red); read with the nearest texel, the
// middle row crosses bands of pure colour: one change of colour with clamp-to-edge (blue up to u = 0.5,
// red after), three with mirrored repeat (red, blue, red, blue) and five with repeat. Bilinear filtering
// (the default) blends the bands into each other. Both paths.
TEST(CrowdRender, SamplersWrapAndFilterTheTexture) {
  REQUIRE_GL();
  struct Kind {
    const char* name;
    Wrap wrap;
    bool nearest;
    int changes;  // of colour along the middle row; -1: blended
  };
  const Kind kinds[] = {{"clamp, nearest", Wrap::kClampToEdge, true, 1},
                        {"mirrored repeat, nearest", Wrap::kMirroredRepeat, true, 3},
                        {"repeat, nearest", Wrap::kRepeat, true, 5},
                        {"repeat, bilinear", Wrap::kRepeat, false, -1}};
  for (const Kind& k : kinds) {
    Model m = square_model();
    for (Vertex& v : m.lods[0].vertices) {
      const float c = std::cos(glm::radians(30.0f)), s = std::sin(glm::radians(30.0f));
      const float x = c * v.position.x + s * (v.position.y - 1.0f);
      v.uv = {x < 0.0f ? -1.0f : 2.0f, 0.5f};
    }
    Texture t;
    t.width = 2;
    t.height = 1;
    t.rgba = {0, 0, 255, 255, 255, 0, 0, 255};
    m.textures = {t};
    m.materials[0].texture = 0;
    m.materials[0].sampler.wrap_s = k.wrap;
    m.materials[0].sampler.mag_nearest = k.nearest;
    auto frames = square_frames(m);
    ASSERT_EQ(frames.size(), 2u);
    for (const auto& [mode, px] : frames) {
      const char* path = mode == RenderMode::kGeometry ? " geometry" : " impostor";
      std::string row;  // the middle row's opaque pixels: R(ed), B(lue) or - (between)
      for (int x = 0; x < 128; ++x) {
        const std::uint8_t* p = &px[(64 * 128 + x) * 4];
        if (p[3] < 255) continue;
        row += p[0] > 100 && p[2] < 10 ? 'R' : p[2] > 100 && p[0] < 10 ? 'B' : '-';
      }
      int changes = 0, between = 0;
      char last = 0;
      for (char ch : row) {
        if (ch == '-') {
          ++between;
          continue;
        }
        changes += last && ch != last;
        last = ch;
      }
      std::printf("%s%s: %s\n", k.name, path, row.c_str());
      EXPECT_GT(row.size(), 50u) << k.name << path;
      if (k.changes >= 0) {
        EXPECT_EQ(changes, k.changes) << k.name << path;
        EXPECT_LE(between, 2 * k.changes + 2) << k.name << path;  // hard edges: a pixel or two each
        EXPECT_EQ(row.front(), k.wrap == Wrap::kMirroredRepeat ? 'R' : 'B') << k.name << path;
      } else {
        EXPECT_GT(between, static_cast<int>(row.size()) / 2) << k.name << path;
      }
    }
  }
}

// The three kinds of material, each drawn by its own shader variant: plain (the flat colour),
// textured (the texture's colour, its alpha ignored) and masked (texels below the cutoff
// discarded), as geometry and as impostors. The texture is 4x1: two blue texels of alpha 0, then
// two red opaque ones; u runs from 0.125 to 0.875 across the square, so the mask keeps half of it.
TEST(CrowdRender, PlainTexturedAndMaskedMaterials) {
  REQUIRE_GL();
  struct Kind {
    const char* name;
    int texture;
    bool mask;
  };
  const Kind kinds[] = {{"plain", -1, false}, {"textured", 0, false}, {"masked", 0, true}};
  struct Counts {
    int covered = 0, red = 0, blue = 0, grey = 0;
  };
  std::map<std::string, Counts> seen;  // "kind geometry" / "kind impostor"
  for (const Kind& k : kinds) {
    Model m = square_model();
    for (Vertex& v : m.lods[0].vertices) {
      // Undo the 30-degree turn of square_model to find the corner's x.
      const float c = std::cos(glm::radians(30.0f)), s = std::sin(glm::radians(30.0f));
      const float x = c * v.position.x + s * (v.position.y - 1.0f);
      v.uv = {x < 0.0f ? 0.125f : 0.875f, 0.5f};
    }
    Texture t;
    t.width = 4;
    t.height = 1;
    t.rgba = {0, 0, 255, 0, 0, 0, 255, 0, 255, 0, 0, 255, 255, 0, 0, 255};
    m.textures = {t};
    m.materials[0].texture = k.texture;
    m.materials[0].alpha_mask = k.mask;
    m.materials[0].alpha_cutoff = 0.5f;
    auto frames = square_frames(m);
    ASSERT_EQ(frames.size(), 2u);
    for (const auto& [mode, px] : frames) {
      Counts n;
      for (std::size_t i = 0; i < px.size(); i += 4) {
        if (px[i + 3] < 255) continue;  // opaque pixels only: the edges blend with nothing
        ++n.covered;
        const int r = px[i], g = px[i + 1], b = px[i + 2];
        n.red += r > 100 && g < 10 && b < 10;
        n.blue += b > 100 && r < 10 && g < 10;
        n.grey += r == g && g == b && r > 100;
      }
      const std::string key = std::string(k.name) + (mode == RenderMode::kGeometry ? " geometry" : " impostor");
      std::printf("%s: %d opaque pixels, %d red, %d blue, %d grey\n", key.c_str(), n.covered, n.red, n.blue, n.grey);
      seen[key] = n;
    }
  }
  for (const char* path : {" geometry", " impostor"}) {
    const Counts& plain = seen[std::string("plain") + path];
    const Counts& textured = seen[std::string("textured") + path];
    const Counts& masked = seen[std::string("masked") + path];
    EXPECT_GT(plain.covered, 2000) << path;
    EXPECT_EQ(plain.grey, plain.covered) << path;  // the flat colour, no texture
    // Textured: the whole square, blue and red in equal parts (measured 35 % each) with the
    // filtered band between them (a third of the square).
    EXPECT_NEAR(textured.covered, plain.covered, plain.covered / 50) << path;
    EXPECT_EQ(textured.red, textured.blue) << path;
    EXPECT_GT(textured.red, textured.covered * 3 / 10) << path;
    // Masked: the red half only (its pure red as in the textured square, the rest the band's
    // half above the cutoff).
    EXPECT_NEAR(masked.covered, plain.covered / 2, plain.covered / 10) << path;
    EXPECT_EQ(masked.blue, 0) << path;
    EXPECT_EQ(masked.red, textured.red) << path;
  }
}

}  // namespace
}  // namespace bb::runtime
