// `idi-workcell sim render [--scene FILE] --out DIR [--json]`: renders the workcell twin's scene
// (shared/sim/scene/scene_file.h; default: the standard workcell scene, workcell/app/scenes/standard.yaml)
// from each of its cameras and writes <camera>.png with the ground truth <camera>.json beside it.
#pragma once

#include <string>
#include <vector>

#include "shared/runtime/cli.h"
#include "shared/sim/scene/image_files.h"
#include "shared/sim/scene/scene_file.h"

namespace idi::workcell {

// Renders every camera of `spec` into `out_dir` (created when missing).
Result<std::vector<sim::WrittenImage>> RenderWorkcellScene(const sim::WorkcellSceneSpec& spec,
                                                           const std::string& out_dir);

// Adds `sim` (when absent) and `sim render` under it.
void AddSimRenderCommand(CliApp& cli);

}  // namespace idi::workcell
