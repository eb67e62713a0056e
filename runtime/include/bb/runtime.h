// bb_runtime: animated impostors for numerous virtual humans (Aubel, Boulic, Thalmann), for games.
// GLM, tinygltf and OpenGL 4.5 only; it never creates windows: the game gives it a current GL
// context (our tools use bb/runtime/headless.h). A game's whole use:
//
//   #include <bb/runtime.h>
//   namespace rt = bb::runtime;
//
//   // Once, with the game's GL 4.5 core context current:
//   bb::Result<rt::Model> model = rt::load_model("walker.glb");       // skinned glTF, MSFT_lod
//   if (!model) { std::puts(model.error().message().c_str()); return; }  // "file: $.path: reason"
//   rt::ImpostorConfig config;                    // windows 256 to 8 px, posture 40 %, view 8 deg
//   config.texels_per_pixel = 1;                  // the test bed's (default 2: finer, slower)
//   config = rt::tuned_config(config, {.samples = 4, .software = rt::software_rasterizer()});
//                                                 // the test bed's measured choices for such a scene
//   rt::Crowd crowd(*model);
//   for (int i = 0; i < 1000; ++i)
//     crowd.add({.position = {2.0f * (i % 40), 0, 2.0f * (i / 40)}, .yaw = 0.1f * i,
//                .clip = 0, .phase = 0.37f * i, .speed = 1.0f});
//   rt::FramePlanner planner(*model, config);     // per-character cache state, atlas allocator
//   auto renderer = rt::Renderer::create(*model, config);  // GPU buffers, atlas pages
//   if (!renderer) { std::puts(renderer.error().message().c_str()); return; }
//
//   // Every frame (move characters by writing crowd[i].position / .yaw; crowd.remove(i) or any edit
//   // of crowd.characters() between frames: each keeps its snapshots by the id crowd.add gave it):
//   rt::SceneCamera cam{.eye = eye, .target = target, .width = w, .height = h};
//   const rt::FramePlan& plan = planner.plan(crowd, cam, seconds, rt::RenderMode::kAuto);
//   (*renderer)->draw(plan);                      // into the bound framebuffer
//   const rt::FrameStats& s = plan.stats;         // geometry, impostors, snapshots, refresh_fraction,
//                                                 // atlas_pages_used, atlas_pixel_use, ...
//   // Several models: a planner, renderer and crowd each, planned together (one call on the
//   // planner's threads), then drawn together. With one atlas for all (model k of n made with
//   // cfg_k = rt::shared_atlas_config(config, k, n), its renderer with
//   // rt::Renderer::create(model_k, cfg_k, renderers[0].get()) after the first), every model's
//   // blended impostors are one back-to-front draw:
//   rt::FramePlanner::plan_many(planners, crowds, cam, seconds, rt::RenderMode::kAuto);
//   rt::Renderer::draw_many(renderers, plans);    // plans[k] = &planners[k]->plan_of_last_frame()
//
// CMake: find_package(bb REQUIRED) then target_link_libraries(game PRIVATE bb::runtime).
#pragma once

#include "bb/result.h"
#include "bb/runtime/animation.h"
#include "bb/runtime/crowd.h"
#include "bb/runtime/impostor.h"
#include "bb/runtime/model.h"
#include "bb/runtime/renderer.h"
#include "bb/runtime/tuning.h"
