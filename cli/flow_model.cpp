// The models the flow test bed uses by default: the built-in body's LOD set and seeded variants of
// it, built once into DIR (each reused when it is already there and newer than the program).
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "bb/exporter/build.h"
#include "bb/modeler/body.h"
#include "bb/result.h"
#include "flow.h"
#include "io.h"

namespace bb::cli {

namespace {

// DIR/<body.name>.glb, built unless it is there and newer than the program.
Result<std::string> built_model(const std::string& dir, const modeler::Body& body) {
  namespace fs = std::filesystem;
  std::string path = (fs::path(dir) / (body.name + ".glb")).string();
  std::error_code ec;
  if (fs::exists(path, ec) && !ec) {
    auto self = fs::last_write_time("/proc/self/exe", ec);
    if (!ec && fs::last_write_time(path, ec) > self) return path;
  }
  auto built = exporter::build_body(body);
  if (!built) return built.error();
  auto st = write_atomic(path, std::string_view(reinterpret_cast<const char*>(built->glb.data()), built->glb.size()));
  if (!st) return st.error();
  return path;
}

}  // namespace

Result<std::vector<std::string>> default_flow_models(const std::string& dir, int variants) {
  std::vector<std::string> paths;
  const modeler::Body base = modeler::default_body();
  for (int k = 0; k <= variants; ++k) {
    // The names `bodybuilder build --variants N --seed 1` gives them.
    auto p = k == 0 ? built_model(dir, base)
                    : built_model(dir, modeler::make_variant(base, {.seed = static_cast<std::uint64_t>(k)},
                                                             "_v" + std::to_string(k)));
    if (!p) return p.error();
    paths.push_back(*p);
  }
  return paths;
}

}  // namespace bb::cli
