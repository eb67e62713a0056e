// bodybuilder mesh [BODY.json] -o DIR [--json] [--seed N] [--format obj|ply]: samples the
// body's skin into the level-of-detail chain (paper section 3.1), writes one mesh file per level,
// report.json, and lods.png, the levels side by side like the paper's figure 2 (a small CPU
// rasterizer: flat-lit triangles with their edges drawn, front and three-quarter views).
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "bb/mesher/mesher.h"
#include "bb/modeler/body.h"
#include "commands.h"
#include "io.h"

namespace bb::cli {
namespace {

std::string to_obj(const mesher::SkinnedMesh& m) {
  std::ostringstream o;
  o << "# bodybuilder mesh: metres, bind posture\n";
  char buf[128];
  for (const auto& p : m.positions) {
    std::snprintf(buf, sizeof buf, "v %.6f %.6f %.6f\n", p.x, p.y, p.z);
    o << buf;
  }
  for (const auto& n : m.normals) {
    std::snprintf(buf, sizeof buf, "vn %.5f %.5f %.5f\n", n.x, n.y, n.z);
    o << buf;
  }
  for (size_t i = 0; i + 2 < m.indices.size(); i += 3) {
    uint32_t a = m.indices[i] + 1, b = m.indices[i + 1] + 1, c = m.indices[i + 2] + 1;
    o << "f " << a << "//" << a << ' ' << b << "//" << b << ' ' << c << "//" << c << '\n';
  }
  return o.str();
}

std::string to_ply(const mesher::SkinnedMesh& m) {
  std::ostringstream o;
  o << "ply\nformat binary_little_endian 1.0\ncomment bodybuilder mesh: metres, bind posture\n"
    << "element vertex " << m.positions.size() << "\nproperty float x\nproperty float y\nproperty float z\n"
    << "property float nx\nproperty float ny\nproperty float nz\n"
    << "element face " << m.triangle_count() << "\nproperty list uchar uint vertex_indices\nend_header\n";
  std::string s = o.str();
  for (size_t i = 0; i < m.positions.size(); ++i) {
    s.append(reinterpret_cast<const char*>(&m.positions[i]), 12);
    s.append(reinterpret_cast<const char*>(&m.normals[i]), 12);
  }
  for (size_t i = 0; i + 2 < m.indices.size(); i += 3) {
    s.push_back(3);
    s.append(reinterpret_cast<const char*>(&m.indices[i]), 12);
  }
  return s;
}

// Orthographic rendering of `m` rotated by `yaw` about Y into a w x h RGBA panel at (x0, 0) of
// an image `iw` wide. `scale` pixels per metre, `center` the world point at the panel centre.
void rasterize(const mesher::SkinnedMesh& m, float yaw, glm::vec3 center, float scale, int x0, int w, int h,
               int iw, std::vector<unsigned char>& rgba, std::vector<float>& depth) {
  const float c = std::cos(yaw), s = std::sin(yaw);
  std::vector<glm::vec3> p(m.positions.size());
  for (size_t i = 0; i < p.size(); ++i) {
    glm::vec3 q = m.positions[i] - center;
    glm::vec3 r(c * q.x + s * q.z, q.y, -s * q.x + c * q.z);  // view looks along -Z
    p[i] = glm::vec3(x0 + w * 0.5f + r.x * scale, h * 0.5f - r.y * scale, r.z);
  }
  const glm::vec3 light = glm::normalize(glm::vec3(-0.4f, 0.5f, 1.0f));
  for (size_t t = 0; t + 2 < m.indices.size(); t += 3) {
    const glm::vec3 &a = p[m.indices[t]], &b = p[m.indices[t + 1]], &cc = p[m.indices[t + 2]];
    float area = (b.x - a.x) * (cc.y - a.y) - (b.y - a.y) * (cc.x - a.x);
    if (area >= 0) continue;  // back-facing (screen y points down)
    glm::vec3 wa = m.positions[m.indices[t]], wb = m.positions[m.indices[t + 1]], wc = m.positions[m.indices[t + 2]];
    glm::vec3 n = glm::normalize(glm::cross(wb - wa, wc - wa));
    glm::vec3 nr(c * n.x + s * n.z, n.y, -s * n.x + c * n.z);
    float shade = 0.25f + 0.75f * std::max(0.0f, glm::dot(nr, light));
    glm::vec3 base(0.86f, 0.72f, 0.62f);
    uint8_t part = m.part.empty() ? 0 : m.part[m.indices[t]];
    if (part != 0) base = glm::vec3(0.70f, 0.74f, 0.86f);
    int minx = std::max(x0, int(std::floor(std::min({a.x, b.x, cc.x})))),
        maxx = std::min(x0 + w - 1, int(std::ceil(std::max({a.x, b.x, cc.x}))));
    int miny = std::max(0, int(std::floor(std::min({a.y, b.y, cc.y})))),
        maxy = std::min(h - 1, int(std::ceil(std::max({a.y, b.y, cc.y}))));
    // Edge lengths in pixels for the wireframe overlay.
    float la = glm::length(glm::vec2(cc - b)), lb = glm::length(glm::vec2(a - cc)), lc = glm::length(glm::vec2(b - a));
    for (int y = miny; y <= maxy; ++y)
      for (int x = minx; x <= maxx; ++x) {
        float px = x + 0.5f, py = y + 0.5f;
        float w0 = ((b.x - px) * (cc.y - py) - (b.y - py) * (cc.x - px)) / area;
        float w1 = ((cc.x - px) * (a.y - py) - (cc.y - py) * (a.x - px)) / area;
        float w2 = 1 - w0 - w1;
        if (w0 < 0 || w1 < 0 || w2 < 0) continue;
        float z = w0 * a.z + w1 * b.z + w2 * cc.z;
        size_t k = size_t(y) * iw + x;
        if (z <= depth[k]) continue;
        depth[k] = z;
        // Distance to the nearest edge in pixels: barycentric * 2 area / edge length.
        float d = std::min({w0 * std::abs(area) / la, w1 * std::abs(area) / lb, w2 * std::abs(area) / lc});
        float edge = d < 0.6f ? 0.55f : 1.0f;
        glm::vec3 col = base * shade * edge;
        rgba[4 * k + 0] = uint8_t(std::clamp(col.r, 0.0f, 1.0f) * 255);
        rgba[4 * k + 1] = uint8_t(std::clamp(col.g, 0.0f, 1.0f) * 255);
        rgba[4 * k + 2] = uint8_t(std::clamp(col.b, 0.0f, 1.0f) * 255);
        rgba[4 * k + 3] = 255;
      }
  }
}

Status write_chain_png(const std::string& path, const std::vector<mesher::Lod>& lods) {
  const int pw = 300, ph = 560;
  const int iw = pw * int(lods.size()), ih = 2 * ph;
  std::vector<unsigned char> rgba(size_t(iw) * ih * 4, 255);
  std::vector<float> depth(size_t(iw) * ih, -1e30f);
  glm::vec3 lo(1e30f), hi(-1e30f);
  for (const auto& q : lods.front().mesh.positions) lo = glm::min(lo, q), hi = glm::max(hi, q);
  glm::vec3 center = 0.5f * (lo + hi);
  float scale = 0.92f * std::min(ph / (hi.y - lo.y), pw / (hi.x - lo.x));
  for (size_t i = 0; i < lods.size(); ++i) {
    std::vector<float> d0(size_t(iw) * ph, -1e30f);
    rasterize(lods[i].mesh, 0.0f, center, scale, int(i) * pw, pw, ph, iw, rgba, d0);
    // Second row: three-quarter view.
    std::vector<unsigned char> row(size_t(iw) * ph * 4, 255);
    std::vector<float> d1(size_t(iw) * ph, -1e30f);
    rasterize(lods[i].mesh, 0.8f, center, scale, int(i) * pw, pw, ph, iw, row, d1);
    for (int y = 0; y < ph; ++y)
      for (int x = int(i) * pw; x < int(i + 1) * pw; ++x)
        for (int k = 0; k < 4; ++k)
          rgba[4 * (size_t(y + ph) * iw + x) + k] = row[4 * (size_t(y) * iw + x) + k];
  }
  return write_png(path, iw, ih, rgba.data());
}

int run_mesh(const std::string& body_path, const std::string& dir, bool as_json, uint64_t seed,
             const std::string& format, bool errors) {
  if (auto st = check_output_dir(dir); !st) {
    std::cerr << "bodybuilder mesh: " << st.error().message() << '\n';
    return 1;
  }
  modeler::Body body;
  if (body_path == "default") {
    body = modeler::default_body();
  } else {
    auto b = modeler::load_body(body_path);
    if (!b) { std::cerr << "bodybuilder mesh: " << b.error().message() << '\n'; return 1; }
    body = std::move(*b);
  }
  if (seed != 0) {
    modeler::BodyShape shape;
    shape.seed = seed;
    body = modeler::make_variant(body, shape, "_seed" + std::to_string(seed));
  }
  mesher::MesherOptions opt;
  if (!errors) opt.error_samples = 0;
  auto lods = mesher::build_lods(body, opt);
  if (!lods) {
    std::cerr << "bodybuilder mesh: " << (body_path == "default" ? std::string("default") : body_path) << ": "
              << lods.error().message() << '\n';
    return 1;
  }
  namespace fs = std::filesystem;
  nlohmann::json report;
  report["kind"] = "lod_chain";
  report["body"] = body.name;
  report["height_m"] = body.height();
  const auto& st = mesher::last_stage_times();
  report["stage_ms"] = {{"field", 1e3 * st.field},       {"contours", 1e3 * st.contours},
                        {"extremities", 1e3 * st.extremities}, {"joining", 1e3 * st.joining},
                        {"refining", 1e3 * st.refining}, {"skinning", 1e3 * st.skinning}, {"checks", 1e3 * st.checks},
                        {"errors", 1e3 * st.errors}};
  report["lods"] = nlohmann::json::array();
  // Without the measurements (--no-errors) the distances are unknown: null, not 0.
  auto measured = [&](double v) { return errors ? nlohmann::json(v) : nlohmann::json(nullptr); };
  for (const auto& l : *lods) {
    const auto& r = l.report;
    std::string file = (fs::path(dir) / ("lod" + std::to_string(r.level) + "." + format)).string();
    Status w = write_atomic(file, format == "ply" ? to_ply(l.mesh) : to_obj(l.mesh));
    if (!w) { std::cerr << "bodybuilder mesh: " << w.error().message() << '\n'; return 1; }
    report["lods"].push_back({{"level", r.level}, {"file", file}, {"triangles", r.triangles},
                              {"vertices", r.vertices}, {"extremity_triangles", r.extremity_triangles},
                              {"vdb_extremities", r.vdb_extremities}, {"hausdorff_m", measured(r.hausdorff_m)},
                              {"mean_m", measured(r.mean_m)}, {"hausdorff_rel", measured(r.hausdorff_rel)},
                              {"mean_rel", measured(r.mean_rel)},
                              {"closed", r.closed}, {"manifold", r.manifold}, {"oriented", r.oriented},
                              {"self_intersections", r.self_intersection_count}, {"ms", 1e3 * r.seconds},
                              {"extremity_hausdorff_m", measured(r.extremity_hausdorff_m)},
                              {"screen_coverage", l.screen_coverage}});
  }
  std::string png = (fs::path(dir) / "lods.png").string();
  Status p = write_chain_png(png, *lods);
  if (!p) { std::cerr << "bodybuilder mesh: " << p.error().message() << '\n'; return 1; }
  report["picture"] = png;
  Status j = write_atomic((fs::path(dir) / "report.json").string(), json_text(report, 1) + "\n");
  if (!j) { std::cerr << "bodybuilder mesh: " << j.error().message() << '\n'; return 1; }
  if (as_json) {
    std::cout << json_text(report) << '\n';
  } else {
    std::printf("%s, %.3f m: %zu levels in %s\n", body.name.c_str(), body.height(), lods->size(), dir.c_str());
    std::printf("lod  triangles (extremities)  vertices  hausdorff (m, %%height)  mean (m, %%height)  extremities (m, %%height)  closed manifold self-x  ms\n");
    for (const auto& l : *lods) {
      const auto& r = l.report;
      std::printf("%3d  %9zu (%6zu)  %8zu  %.4f %6.3f%%        %.5f %6.3f%%    %.4f %6.3f%%            %d      %d      %4zu  %6.1f\n",
                  r.level, r.triangles, r.extremity_triangles, r.vertices, r.hausdorff_m, 100 * r.hausdorff_rel,
                  r.mean_m, 100 * r.mean_rel, r.extremity_hausdorff_m, 100 * r.extremity_hausdorff_m / body.height(),
                  r.closed, r.manifold, r.self_intersection_count, 1e3 * r.seconds);
    }
    std::printf("stages (ms): field %.1f, contours %.1f, extremities %.1f, joining %.1f, refining %.1f, skinning %.1f, "
                "checks %.1f, errors %.1f\n",
                1e3 * st.field, 1e3 * st.contours, 1e3 * st.extremities, 1e3 * st.joining, 1e3 * st.refining, 1e3 * st.skinning,
                1e3 * st.checks, 1e3 * st.errors);
    std::printf("wrote %s and one %s per level\n", png.c_str(), format.c_str());
  }
  return 0;
}

void add_mesh_command(CLI::App& app, int* status) {
  auto* cmd = app.add_subcommand("mesh", "Sample a body's skin into skinned LOD meshes (OBJ/PLY, report, picture)");
  auto body = std::make_shared<std::string>("default");
  auto dir = std::make_shared<std::string>("out/mesh");
  auto json = std::make_shared<bool>(false);
  auto seed = std::make_shared<uint64_t>(0);
  auto format = std::make_shared<std::string>("obj");
  auto no_errors = std::make_shared<bool>(false);
  cmd->add_option("body", *body, "Body JSON file, or 'default' for the built-in body")->capture_default_str();
  cmd->add_option("-o,--output", *dir, "Output folder")->capture_default_str();
  cmd->add_flag("--json", *json, "Print the report as one JSON object");
  cmd->add_option("--seed", *seed, "Mesh a random variant of the body (make_variant with this seed; 0: the body itself)")
      ->check(whole_number());
  cmd->add_option("--format", *format, "Mesh file format")->check(CLI::IsMember({"obj", "ply"}))->capture_default_str();
  cmd->add_flag("--no-errors", *no_errors, "Skip the distance measurements (faster)");
  cmd->callback([=] { *status = run_mesh(*body, *dir, *json, *seed, *format, !*no_errors); });
}

const Registrar registrar(30, add_mesh_command);

}  // namespace
}  // namespace bb::cli
