// The flow test bed on the runtime alone, so that it can run on a machine that has a GPU but not
// the offline pipeline's libraries:
//   bench_flow MODEL.glb OUT_DIR [frames] [scaling sizes]: the main run (20 humans, both paths),
//     both sweeps and the crowd sizes; writes OUT_DIR/*.json|csv|png.
//   bench_flow flow --model MODEL.glb [any flag of `bodybuilder flow`]: that command, as is.
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

#include "commands.h"
#include "flow.h"

namespace bb::cli {
// flow.cpp asks for the built-in models only when no --model is given; here one always is.
Result<std::vector<std::string>> default_flow_models(const std::string&, int) {
  return Error{"", "", "bench_flow needs a model file (--model)"};
}
}  // namespace bb::cli

int main(int argc, char** argv) {
  if (argc >= 2 && std::strcmp(argv[1], "flow") == 0) {
    CLI::App app{"bench_flow: the flow test bed on the runtime alone", "bench_flow"};
    return bb::cli::run_command_line(app, argc, argv);  // flow.cpp registers `flow`
  }
  if (argc < 3) {
    std::fprintf(stderr, "usage: bench_flow MODEL.glb OUT_DIR [frames] [sizes, e.g. 20,100,1000,10000]\n");
    return 2;
  }
  bb::cli::FlowArgs a;
  a.models = {argv[1]};
  a.out = argv[2];
  a.frames = argc > 3 ? std::atoi(argv[3]) : 60;
  std::string sizes = argc > 4 ? argv[4] : "20,100,500,1000,2000,5000,10000";
  nlohmann::ordered_json r;
  int st = bb::cli::run_flow_command(a, &r);
  if (st) return st;
  for (const char* sweep : {"posture", "view"}) {
    bb::cli::FlowArgs s = a;
    s.out = a.out + "/" + sweep;
    s.sweep = sweep;
    if ((st = bb::cli::run_flow_command(s, nullptr))) return st;
  }
  bb::cli::FlowArgs sc = a;
  sc.out = a.out + "/scaling";
  sc.frames = 2;
  sc.scaling = true;
  sc.scaling_list = sizes;
  sc.scaling_frames = 5;
  return bb::cli::run_flow_command(sc, nullptr);
}
