// bodybuilder build [BODY.json ...] -o DIR [--variants N --seed S [--variants-only]] [--motion CLIP.bvh ...]
//                   [--lods K] [--per-lod-files] [--jobs J] [--json]
// Many inputs are one batch: each is reported, a failure does not stop the others, the exit
// status is non-zero if any failed; jobs run on all cores; progress goes to stderr.
#include <algorithm>
#include <cmath>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <mutex>
#include <thread>

#include <nlohmann/json.hpp>

#include "bb/exporter/build.h"
#include "bb/modeler/body.h"
#include "bb/motion/bvh.h"
#include "commands.h"
#include "io.h"
#include "bb/parallel.h"

namespace bb::cli {

namespace {

namespace fs = std::filesystem;

struct BuildArgs {
  std::vector<std::string> bodies, motions;
  std::string out = "out";
  int variants = 0, lods = 4, jobs = 0;
  bool variants_only = false;
  unsigned inner_threads = 0;  // threads inside one body's build (1 when bodies run in parallel)
  uint64_t seed = 1;
  bool json = false, per_lod = false, no_errors = false;
};

struct Job {
  std::string input;                 // file, or "default"
  std::shared_ptr<const modeler::Body> base;  // null when loading failed
  std::string load_error;
  bool variant = false;              // false: the body itself; true: the variant of this seed
  uint64_t seed = 0;
  std::string name;
  // results
  bool ok = false;
  std::string output, error;
  double seconds = 0;
  exporter::BuildTimes times;
  float walk_arm_abduction_deg = 0;  // how far out the walk's arms hang (a heavy body's further)
  std::vector<mesher::LodReport> lods;
  // Levels that fail their own checks (not closed, not manifold, self-intersecting): still written,
  // and said on stderr and in --json, so that a batch of variants shows which to look at.
  std::vector<std::string> warnings;
};

void run_job(Job& job, const BuildArgs& a) {
  auto t0 = std::chrono::steady_clock::now();
  auto finish = [&] { job.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(); };
  if (!job.base) {
    job.error = job.load_error;
    finish();
    return;
  }
  modeler::Body body = job.variant ? modeler::make_variant(*job.base, {.seed = job.seed}, job.name.substr(job.base->name.size()))
                                : *job.base;
  job.name = body.name;
  exporter::BuildOptions opt;
  opt.lods = a.lods;
  opt.measure_errors = !a.no_errors;
  opt.threads = a.inner_threads;
  for (const auto& m : a.motions) {
    auto clip = motion::load_bvh(m, *body.skeleton);
    if (!clip) {
      job.error = clip.error().message();
      finish();
      return;
    }
    opt.extra_clips.push_back(std::move(*clip));
  }
  auto built = exporter::build_body(body, opt);
  if (!built) {
    job.error = (job.input == "default" ? "" : job.input + ": ") + built.error().message();
    finish();
    return;
  }
  job.output = (fs::path(a.out) / (body.name + ".glb")).string();
  std::string_view bytes(reinterpret_cast<const char*>(built->glb.data()), built->glb.size());
  if (auto st = write_atomic(job.output, bytes); !st) {
    job.error = st.error().message();
    finish();
    return;
  }
  if (a.per_lod) {
    for (size_t l = 0; l < built->input.lods.size(); ++l) {
      auto one = exporter::encode_glb_level(built->input, static_cast<int>(l));
      if (!one) { job.error = one.error().message(); finish(); return; }
      std::string p = (fs::path(a.out) / (body.name + "_lod" + std::to_string(l) + ".glb")).string();
      if (auto st = write_atomic(p, std::string_view(reinterpret_cast<const char*>(one->data()), one->size())); !st) {
        job.error = st.error().message();
        finish();
        return;
      }
    }
  }
  job.times = built->times;
  job.walk_arm_abduction_deg = built->walk_arm_abduction_rad * 57.29578f;
  for (const auto& l : built->input.lods) {
    const mesher::LodReport& r = l.report;
    job.lods.push_back(r);
    std::string what;
    if (!r.closed) what += ", not closed";
    if (!r.manifold) what += ", not manifold";
    if (r.self_intersection_count > 0) what += ", " + std::to_string(r.self_intersection_count) + " pairs of triangles intersect";
    if (!what.empty()) job.warnings.push_back(job.output + ": level " + std::to_string(r.level) + what);
  }
  job.ok = true;
  finish();
}

int run(BuildArgs a) {
  if (a.lods < 2 || a.lods > 8) {
    std::cerr << "bodybuilder build: --lods: expected 2 to 8 (got " << a.lods << ")\n";
    return 2;
  }
  if (a.variants_only && a.variants < 1) {
    std::cerr << "bodybuilder build: --variants-only needs --variants N with N >= 1\n";
    return 2;
  }
  if (a.jobs < 0) {
    std::cerr << "bodybuilder build: --jobs: expected 0 (one per core) or more (got " << a.jobs << ")\n";
    return 2;
  }
  if (a.variants < 0) {
    std::cerr << "bodybuilder build: --variants: expected >= 0\n";
    return 2;
  }
  if (auto st = check_output_dir(a.out); !st) {
    std::cerr << "bodybuilder build: " << st.error().message() << "\n";
    return 1;
  }
  // Each clip is named after its file (the glTF animation's name, what --clip picks): names must be
  // valid UTF-8 and differ.
  for (std::size_t k = 0; k < a.motions.size(); ++k) {
    const std::string& m = a.motions[k];
    std::error_code ec;
    const char* why = !fs::exists(m, ec) ? "no such file" : fs::is_directory(m, ec) ? "is a folder, not a BVH file" : nullptr;
    const std::string clip = fs::path(m).stem().string();
    if (!why && !valid_utf8(clip)) why = "the clip is named after the file, and this file name is not valid UTF-8";
    for (std::size_t e = 0; !why && e < k; ++e)
      if (fs::path(a.motions[e]).stem().string() == clip) why = "the clip is named after the file, and an earlier --motion has the same name";
    if (why) {
      std::cerr << "bodybuilder build: --motion: " << m << ": " << why << "\n";
      return 2;
    }
  }
  if (a.bodies.empty()) a.bodies.push_back("default");
  std::vector<Job> jobs;
  for (const auto& in : a.bodies) {
    Job base;
    base.input = in;
    if (in == "default") {
      base.base = std::shared_ptr<const modeler::Body>(&modeler::default_body(), [](const modeler::Body*) {});
    } else {
      auto b = modeler::load_body(in);
      if (b) base.base = std::make_shared<modeler::Body>(std::move(*b));
      else base.load_error = b.error().message();
    }
    base.name = base.base ? base.base->name : fs::path(in).stem().string();
    if (!a.variants_only || !base.base) jobs.push_back(base);  // a body that failed to load is reported anyway
    for (int v = 0; v < a.variants; ++v) {
      Job var = base;
      var.variant = true;
      var.seed = a.seed + static_cast<uint64_t>(v);
      var.name = base.name + "_v" + std::to_string(var.seed);
      jobs.push_back(var);
    }
  }
  // Two jobs writing one file (bodies named alike, or a body named like another's variant) would
  // leave whichever finished last: the later ones fail instead, naming the earlier input.
  {
    std::vector<std::pair<std::string, std::string>> written;  // output file name, the job's input
    for (Job& job : jobs) {
      if (!job.base) continue;
      std::vector<std::string> names{job.name + ".glb"};
      for (int l = 0; a.per_lod && l < a.lods; ++l) names.push_back(job.name + "_lod" + std::to_string(l) + ".glb");
      for (const auto& n : names)
        for (const auto& [other, input] : written)
          if (n == other && job.load_error.empty()) {
            job.base.reset();
            job.load_error = (job.input == "default" ? "" : job.input + ": ") + "would write " +
                             (fs::path(a.out) / n).string() + ", as " + (input == "default" ? "the built-in body" : input) +
                             " does (bodies with the same name; rename one)";
          }
      if (job.base)
        for (const auto& n : names) written.emplace_back(n, job.input);
    }
  }
  int workers = a.jobs > 0 ? a.jobs : static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  workers = std::min<int>(workers, static_cast<int>(jobs.size()));
  a.inner_threads = workers > 1 ? 1 : 0;
  std::atomic<int> done{0};
  std::mutex io;
  bool batch = jobs.size() > 1;
  auto t0 = std::chrono::steady_clock::now();
  parallel_for(jobs.size(), static_cast<unsigned>(std::max(1, workers)), [&](std::size_t i) {
    run_job(jobs[i], a);
    int d = ++done;
    std::lock_guard<std::mutex> lock(io);
    if (batch || !a.json)
      std::fprintf(stderr, "[%d/%zu] %s: %s (%.2f s)\n", d, jobs.size(), jobs[i].name.c_str(),
                   jobs[i].ok ? jobs[i].output.c_str() : ("FAILED: " + jobs[i].error).c_str(), jobs[i].seconds);
    for (const auto& w : jobs[i].warnings) std::fprintf(stderr, "bodybuilder build: warning: %s\n", w.c_str());
  });
  double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  int failed = static_cast<int>(std::count_if(jobs.begin(), jobs.end(), [](const Job& j) { return !j.ok; }));
  if (a.json) {
    nlohmann::ordered_json j;
    j["outputs"] = nlohmann::ordered_json::array();
    for (const auto& job : jobs) {
      nlohmann::ordered_json o;
      o["input"] = job.input;
      o["name"] = job.name;
      o["output"] = job.ok ? nlohmann::ordered_json(job.output) : nlohmann::ordered_json(nullptr);
      o["ok"] = job.ok;
      o["seconds"] = job.seconds;
      o["error"] = job.ok ? nlohmann::ordered_json(nullptr) : nlohmann::ordered_json(job.error);
      if (job.ok) {
        o["stages_s"] = {{"mesh", job.times.mesh}, {"decimate", job.times.decimate}, {"checks", job.times.checks}, {"proxies", job.times.proxies},
                         {"clips", job.times.clips}, {"encode", job.times.encode}};
        nlohmann::ordered_json lods = nlohmann::ordered_json::array();
        for (const auto& r : job.lods)
          lods.push_back({{"triangles", r.triangles}, {"hausdorff_rel", a.no_errors ? nlohmann::ordered_json(nullptr) : nlohmann::ordered_json(r.hausdorff_rel)}, {"closed", r.closed},
                          {"manifold", r.manifold}, {"self_intersections", r.self_intersection_count}});
        o["lods"] = lods;
        o["walk_arm_abduction_deg"] = std::round(double(job.walk_arm_abduction_deg) * 10) / 10;
        o["warnings"] = job.warnings;
      }
      j["outputs"].push_back(o);
    }
    j["failed"] = failed;
    j["wall_seconds"] = wall;
    j["workers"] = workers;
    std::cout << json_text(j) << "\n";
  } else {
    std::printf("built %zu of %zu in %.2f s on %d worker%s\n", jobs.size() - failed, jobs.size(), wall, workers,
                workers == 1 ? "" : "s");
  }
  return failed ? 1 : 0;
}

void add_build_command(CLI::App& app, int* status) {
  auto* cmd = app.add_subcommand("build", "Build skinned, animated glTF LOD sets (.glb) from body files");
  auto a = std::make_shared<BuildArgs>();
  cmd->add_option("BODY", a->bodies, "Body JSON files (none: the built-in default body)");
  cmd->add_option("-o,--output", a->out, "Output folder: one DIR/<name>.glb per body")->capture_default_str();
  cmd->add_option("--variants", a->variants, "Also write N seeded variants of each body")->capture_default_str();
  cmd->add_flag("--variants-only", a->variants_only, "Write only the variants, not the bodies they vary");
  cmd->add_option("--seed", a->seed, "Seed of the first variant (then seed+1, ...), >= 0")
      ->capture_default_str()
      ->check(whole_number());
  cmd->add_option("--motion", a->motions, "A BVH clip to retarget and add as an animation named after the file (repeat for more)")
      ->allow_extra_args(false);
  cmd->add_option("--lods", a->lods, "Levels of detail, 2..8")->capture_default_str();
  cmd->add_flag("--per-lod-files", a->per_lod, "Also write DIR/<name>_lod<k>.glb, one level each");
  cmd->add_flag("--no-errors", a->no_errors, "Skip measuring each level's distance to the skin (faster)");
  cmd->add_option("--jobs", a->jobs, "Parallel jobs (0: one per core)")->capture_default_str();
  cmd->add_flag("--json", a->json, "Print one JSON object on stdout");
  cmd->callback([=] { *status = run(*a); });
}

const Registrar registrar(30, add_build_command);

}  // namespace
}  // namespace bb::cli
