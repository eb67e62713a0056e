// The model the flow test bed uses by default: the built-in body's LOD set, built once into
// DIR/default.glb (reused when it is already there and newer than the program).
#include <filesystem>
#include <string>

#include "bb/exporter/build.h"
#include "bb/modeler/body.h"
#include "bb/result.h"
#include "io.h"

namespace bb::cli {

Result<std::string> default_flow_model(const std::string& dir) {
  namespace fs = std::filesystem;
  std::string path = (fs::path(dir) / "default.glb").string();
  std::error_code ec;
  if (fs::exists(path, ec) && !ec) {
    auto self = fs::last_write_time("/proc/self/exe", ec);
    if (!ec && fs::last_write_time(path, ec) > self) return path;
  }
  auto built = exporter::build_body(modeler::default_body());
  if (!built) return built.error();
  auto st = write_atomic(path, std::string_view(reinterpret_cast<const char*>(built->glb.data()), built->glb.size()));
  if (!st) return st.error();
  return path;
}

}  // namespace bb::cli
