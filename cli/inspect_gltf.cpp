#include <iostream>
#include <string>

namespace bb::cli {

int inspect_gltf(const std::string& path, bool /*as_json*/) {
  std::cerr << "bodybuilder inspect: " << path << ": glTF inspection is not implemented yet\n";
  return 3;
}

}  // namespace bb::cli
