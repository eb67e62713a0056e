// The skeleton and body built into the program, parsed once on first use.
#include <cstdio>
#include <cstdlib>

#include "bb/modeler/body.h"
#include "bb/modeler/skeleton.h"

namespace bb::embedded {
extern const char* const kSkeletonJson;
extern const char* const kDefaultBodyJson;
}  // namespace bb::embedded

namespace bb::modeler {

const Skeleton& default_skeleton() {
  static const Skeleton sk = [] {
    auto r = parse_skeleton(embedded::kSkeletonJson, "<built-in data/skeleton.json>");
    if (!r) {  // a build error, not a user error: the data file was checked by the tests
      std::fprintf(stderr, "%s\n", r.error().message().c_str());
      std::abort();
    }
    return std::move(*r);
  }();
  return sk;
}

const Body& default_body() {
  static const Body body = [] {
    // The body file names "../skeleton.json"; the built-in body uses the built-in skeleton.
    std::string text = embedded::kDefaultBodyJson;
    auto r = parse_body(text, "<built-in data/bodies/default.json>", "<built-in>");
    if (!r) {
      std::fprintf(stderr, "%s\n", r.error().message().c_str());
      std::abort();
    }
    return std::move(*r);
  }();
  return body;
}

}  // namespace bb::modeler
