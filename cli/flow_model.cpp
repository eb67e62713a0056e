// The models the flow test bed uses by default: the built-in body's LOD set and seeded variants of
// it, built once into DIR (each reused while it is the file flow wrote there with this program).
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "bb/exporter/build.h"
#include "bb/modeler/body.h"
#include "bb/result.h"
#include "flow.h"
#include "io.h"

namespace bb::cli {

namespace {

// What flow remembers of a LOD set it wrote: DIR/.<name>.glb.flow, "<bytes> <mtime ns>" of the file
// as written and of the program that wrote it. A file that is not the one this program wrote (a user's
// `bodybuilder build` of another body of the same name, another program's: an older or newer build,
// another checkout's, whose bodies may differ) is built again rather than drawn as the built-in crowd.
std::string flow_stamp(const std::string& path) {
  namespace fs = std::filesystem;
  std::string stamp;
  for (const std::string& p : {path, std::string("/proc/self/exe")}) {
    std::error_code ec;
    const fs::path file = fs::canonical(p, ec);
    if (ec) return {};
    const auto size = fs::file_size(file, ec);
    if (ec) return {};
    const auto time = fs::last_write_time(file, ec);
    if (ec) return {};
    stamp += std::to_string(size) + " " + std::to_string(time.time_since_epoch().count()) + "\n";
  }
  return stamp;
}

std::string stamp_path(const std::string& path) {
  namespace fs = std::filesystem;
  const fs::path p(path);
  std::string name = p.filename().string();
  name.insert(name.begin(), '.');
  name.append(".flow");
  return (p.parent_path() / name).string();
}

// DIR/<body.name>.glb, built unless flow wrote it there with this program (newer than the program,
// and unchanged since: its stamp, which names the program too).
Result<std::string> built_model(const std::string& dir, const modeler::Body& body) {
  namespace fs = std::filesystem;
  std::string path = (fs::path(dir) / (body.name + ".glb")).string();
  std::error_code ec;
  if (fs::is_regular_file(path, ec) && !ec) {
    auto self = fs::last_write_time("/proc/self/exe", ec);
    if (!ec && fs::last_write_time(path, ec) > self && !ec) {
      std::ifstream in(stamp_path(path), std::ios::binary);
      std::string kept((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
      const std::string now = flow_stamp(path);
      if (!now.empty() && kept == now) return path;
    }
  }
  auto built = exporter::build_body(body);
  if (!built) return built.error();
  auto st = write_atomic(path, std::string_view(reinterpret_cast<const char*>(built->glb.data()), built->glb.size()));
  if (!st) return st.error();
  // The stamp is only a cache note: without it the file is built again next time.
  if (const std::string stamp = flow_stamp(path); !stamp.empty()) (void)write_atomic(stamp_path(path), stamp);
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
