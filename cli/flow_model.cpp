// The model the flow test bed uses by default: the built-in body's LOD set.
#include <string>

#include "bb/result.h"

namespace bb::cli {

Result<std::string> default_flow_model(const std::string& /*dir*/) {
  return Error{"", "", "the built-in body's glTF LOD set is not available yet: pass --model FILE.glb"};
}

}  // namespace bb::cli
