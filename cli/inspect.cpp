// bodybuilder inspect BODY.json|FILE.glb [--json] [--preview PNG]
#include <cctype>
#include <filesystem>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "bb/modeler/body.h"
#include "bb/modeler/implicit_surface.h"
#include "commands.h"
#include "io.h"

namespace bb::cli {

namespace {

// Whether `s` ends in `suf` (lower case), whatever the case of `s` ("FOX.GLB" is a glTF too).
bool has_suffix(const std::string& s, const std::string& suf) {
  if (s.size() < suf.size()) return false;
  for (std::size_t k = 0; k < suf.size(); ++k)
    if (std::tolower(static_cast<unsigned char>(s[s.size() - suf.size() + k])) != suf[k]) return false;
  return true;
}

// A CPU ray-cast picture of the skin: front and side views, shaded by the field's gradient.
std::vector<unsigned char> preview(const modeler::Body& body, const modeler::Posture& posture, int h,
                                   int* width) {
  modeler::ImplicitSurface s(body, posture);
  const auto& b = s.bounds();
  float extent = std::max(b.size().y, std::max(b.size().x, b.size().z)) * 1.02f;
  float px = extent / h;
  int w = h;  // two square views side by side
  *width = 2 * w;
  std::vector<unsigned char> img(static_cast<size_t>(2 * w) * h * 4, 0);
  glm::vec3 c = b.center();
  glm::vec3 light = glm::normalize(glm::vec3(0.4f, 0.6f, 0.7f));
  for (int view = 0; view < 2; ++view) {
    // view 0: from the front (+Z looking at -Z); view 1: from the body's left (+X).
    glm::vec3 dir = view == 0 ? glm::vec3(0, 0, 1) : glm::vec3(1, 0, 0);
    glm::vec3 right = view == 0 ? glm::vec3(1, 0, 0) : glm::vec3(0, 0, -1);
    float depth = glm::dot(b.size(), glm::abs(dir)) + 0.02f;
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x) {
        glm::vec3 o = c + right * ((x + 0.5f - w * 0.5f) * px) + glm::vec3(0, 1, 0) * ((h * 0.5f - y - 0.5f) * px) -
                      dir * (0.5f * depth);
        auto t = s.outermost_intersection(o, dir, depth);
        if (!t) continue;
        glm::vec3 g;
        s.field_gradient(o + dir * *t, &g);
        glm::vec3 n = -glm::normalize(g);
        float l = 0.25f + 0.75f * std::max(0.0f, glm::dot(n, light));
        unsigned char* p = &img[(static_cast<size_t>(y) * 2 * w + view * w + x) * 4];
        p[0] = static_cast<unsigned char>(std::min(255.0f, 235 * l));
        p[1] = static_cast<unsigned char>(std::min(255.0f, 190 * l));
        p[2] = static_cast<unsigned char>(std::min(255.0f, 160 * l));
        p[3] = 255;
      }
  }
  return img;
}

}  // namespace

int run_inspect_body(const std::string& path, bool as_json, const std::string& preview_path,
                     const std::string& posture_name, const char* command) {
  auto t0 = std::chrono::steady_clock::now();
  Result<modeler::Body> loaded = path == "default" ? Result<modeler::Body>(modeler::default_body())
                                                   : modeler::load_body(path);
  if (!loaded) {
    std::cerr << "bodybuilder " << command << ": " << loaded.error().message() << "\n";
    return 1;
  }
  const modeler::Body& body = *loaded;
  const modeler::Skeleton& sk = *body.skeleton;
  int limited = 0;
  for (int i = 0; i < sk.dof_count(); ++i) {
    const auto& d = sk.dof(i);
    if (std::isfinite(d.min) && std::isfinite(d.max) && d.min <= d.max) ++limited;
  }
  float height = body.height();
  glm::vec3 ta = sk.ta();
  int ne = body.count(modeler::PrimitiveType::kEllipsoid), nm = body.count(modeler::PrimitiveType::kMetaball);
  double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  // An unknown posture is an error with or without --preview (which is what it is for).
  std::vector<std::string> names = sk.posture_names();
  if (std::find(names.begin(), names.end(), "neutral") == names.end()) names.insert(names.begin(), "neutral");
  if (std::find(names.begin(), names.end(), posture_name) == names.end()) {
    std::string known;
    for (const std::string& n : names) known += (known.empty() ? "" : ", ") + n;
    std::cerr << "bodybuilder " << command << ": --posture: unknown posture \"" << posture_name << "\" (known: " << known << ")\n";
    return 2;
  }
  if (!preview_path.empty()) {
    int w = 0, h = 512;
    auto img = preview(body, sk.posture(posture_name), h, &w);
    if (auto st = write_png(preview_path, w, h, img.data()); !st) {
      std::cerr << "bodybuilder " << command << ": " << st.error().message() << "\n";
      return 1;
    }
  }
  if (as_json) {
    nlohmann::ordered_json j;
    j["kind"] = "body";
    j["name"] = body.name;
    j["file"] = path;
    j["joints"] = sk.joints().size();
    j["dofs"] = sk.dof_count();
    j["dofs_with_limits"] = limited;
    j["primitives"] = {{"ellipsoid", ne}, {"metaball", nm}};
    j["height_m"] = std::round(height * 1e4) / 1e4;
    j["ta"] = {ta.x, ta.y, ta.z};
    j["postures"] = sk.posture_names();
    j["limits_source"] = sk.limits_source;
    j["seconds"] = seconds;
    if (!preview_path.empty()) j["preview"] = preview_path;
    std::cout << json_text(j) << "\n";
  } else {
    std::printf("body %s (%s)\n", body.name.c_str(), path.c_str());
    std::printf("  skeleton   %s: %zu joints, %d DOFs (%d with limits)\n", sk.name.c_str(), sk.joints().size(),
                sk.dof_count(), limited);
    std::printf("  primitives %d ellipsoids (bone), %d metaballs (muscle and fat)\n", ne, nm);
    std::printf("  height     %.3f m (neutral posture)\n", height);
    std::printf("  Ta         (%.3f, %.3f, %.3f) m, spine base in the maximal-extent posture\n", ta.x, ta.y, ta.z);
    if (!preview_path.empty()) std::printf("  preview    %s\n", preview_path.c_str());
  }
  return 0;
}

int inspect_gltf(const std::string& path, bool as_json, int lod_levels);  // inspect_gltf.cpp

namespace {
void add_inspect_command(CLI::App& app, int* status) {
  auto* cmd = app.add_subcommand("inspect", "Describe a body file (.json) or a skinned glTF (.glb/.gltf)");
  auto file = std::make_shared<std::string>("default");
  auto as_json = std::make_shared<bool>(false);
  auto preview_path = std::make_shared<std::string>();
  auto posture = std::make_shared<std::string>("bind");
  auto lod_levels = std::make_shared<int>(0);
  cmd->add_option("FILE", *file, "BODY.json, FILE.glb or FILE.gltf; 'default' is the built-in body")
      ->capture_default_str();
  cmd->add_flag("--json", *as_json, "Print one JSON object on stdout");
  cmd->add_option("--preview", *preview_path, "Bodies: write a ray-cast PNG of the skin (front and side)");
  cmd->add_option("--posture", *posture, "Bodies: posture of the preview (neutral, bind, max_extent)")
      ->capture_default_str();
  cmd->add_option("--lods", *lod_levels,
                  "glTF with one level: also describe the N coarser levels the runtime makes at load "
                  "(flow and render make 3 by default; see their --lods)")
      ->capture_default_str()
      ->check(whole_number(0, 8));
  cmd->callback([=] {
    std::error_code ec;
    if (file->empty() || std::filesystem::is_directory(*file, ec)) {
      std::cerr << "bodybuilder inspect: " << (file->empty() ? "(empty file name): no file given" : *file + ": is a folder, not a file")
                << "\n";
      *status = 1;
      return;
    }
    if (!preview_path->empty())
      if (auto st = check_output_file(*preview_path); !st) {
        std::cerr << "bodybuilder inspect: --preview: " << st.error().message() << "\n";
        *status = 1;
        return;
      }
    if (has_suffix(*file, ".glb") || has_suffix(*file, ".gltf"))
      *status = inspect_gltf(*file, *as_json, *lod_levels);
    else
      *status = run_inspect_body(*file, *as_json, *preview_path, *posture, "inspect");
  });
}

const Registrar registrar(20, add_inspect_command);
}  // namespace

}  // namespace bb::cli
