#include "workcell/app/replay_command.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <cmath>
#include <filesystem>
#include <iostream>
#include <map>
#include <nlohmann/json.hpp>

#include "shared/replay/recording.h"
#include "shared/util/atomic_file.h"
#include "workcell/procedures/structure.h"
#ifdef IDI_HAVE_RAWLOG
#include "shared/replay/rawlog_export.h"
#endif

namespace idi::workcell {
namespace {

struct ReplayOptions {
  std::string dir;
  bool json = false;
};

Result<Rigid3d> PoseFromEvent(const nlohmann::json& e, const std::string& where) {
  const auto bad = [&] { return ParseError(where + ": image event without a 12-number cam_from_world"); };
  if (!e.contains("cam_from_world") || !e["cam_from_world"].is_array() || e["cam_from_world"].size() != 12)
    return bad();
  double m[12];
  for (std::size_t i = 0; i < 12; ++i) {
    // A NaN is written as null by the JSON writer: not a pose to reconstruct from.
    const nlohmann::json& v = e["cam_from_world"][i];
    if (!v.is_number() || !std::isfinite(v.get<double>())) return bad();
    m[i] = v.get<double>();
  }
  Rigid3d t;
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) t.rotation(r, c) = m[4 * r + c];
    t.translation(r) = m[4 * r + 3];
  }
  return t;
}

// A string field of an event; `fallback` when it is absent, an error naming the event when it is not a string.
Result<std::string> StringField(const nlohmann::json& e,
                                const char* key,
                                const std::string& fallback,
                                const std::string& where) {
  if (!e.contains(key)) return fallback;
  if (!e[key].is_string()) return ParseError(where + ": '" + key + "' is not a string");
  return e[key].get<std::string>();
}

Status ReplayScan(const Recording& rec, bool json) {
  std::vector<StructureView> views;
  for (std::size_t k = 0; k < rec.events.size(); ++k) {
    const nlohmann::json& e = rec.events[k];
    if (e.value("type", "") != "image") continue;
    const std::string where = fmt::format("{}/events.jsonl event {}", rec.dir, k + 1);
    IDI_ASSIGN_OR_RETURN(const std::string camera, StringField(e, "camera", "", where));
    const auto cam = rec.header.cameras.find(camera);
    if (cam == rec.header.cameras.end()) return ParseError(where + ": camera '" + camera + "' not in the header");
    StructureView v;
    IDI_ASSIGN_OR_RETURN(v.name, StringField(e, "file", "", where));
    v.camera = cam->second;
    IDI_ASSIGN_OR_RETURN(v.cam_from_world, PoseFromEvent(e, where));
    IDI_ASSIGN_OR_RETURN(v.image, LoadRecordedImage(rec, e));
    views.push_back(std::move(v));
  }
  IDI_ASSIGN_OR_RETURN(const StructureResult r, ReconstructStructure(views, StructureOptions{}));
  nlohmann::json out;
  out["kind"] = "scan";
  out["views"] = views.size();
  out["points"] = nlohmann::json::array();
  for (const ModelPoint& p : r.model.points) {
    out["points"].push_back(
        {{"id", p.id}, {"xyz_mm", {p.xyz.x(), p.xyz.y(), p.xyz.z()}}, {"reproj_rms_px", p.reprojection_rms_px}});
  }
  out["edges"] = r.model.edges;
  if (rec.header.meta.contains("points")) out["recorded_points"] = rec.header.meta["points"];
  if (json) {
    std::cout << out.dump() << "\n";
  } else {
    std::cout << fmt::format("replayed scan {}: {} views -> {} points, {} edges (recorded run: {} points)\n",
                             rec.dir,
                             views.size(),
                             r.model.points.size(),
                             r.model.edges.size(),
                             rec.header.meta.value("points", -1));
  }
  return Status::Ok();
}

Status RunReplay(const ReplayOptions& o) {
  IDI_ASSIGN_OR_RETURN(const Recording rec, ReadRecording(o.dir));
  if (rec.truncated) {
    spdlog::warn("{}/events.jsonl:{}: the recording ends with a torn line (the run was interrupted); skipped",
                 o.dir,
                 rec.truncated_line);
  }
  if (rec.header.kind == "scan") return ReplayScan(rec, o.json);
  // Other runs: what was recorded, by event type.
  std::map<std::string, int> counts;
  for (const auto& e : rec.events) ++counts[e.value("type", "?")];
  nlohmann::json out{{"kind", rec.header.kind}, {"events", counts}, {"meta", rec.header.meta}};
  if (o.json) {
    std::cout << out.dump() << "\n";
  } else {
    std::cout << fmt::format("{} run in {}: {} events\n", rec.header.kind, o.dir, rec.events.size());
    for (const auto& [type, n] : counts) std::cout << fmt::format("  {:10s} {}\n", type, n);
  }
  return Status::Ok();
}

#ifdef IDI_HAVE_RAWLOG
struct ExportOptions {
  std::string dir;
  std::string out;
};

Status RunExport(const ExportOptions& o) {
  IDI_ASSIGN_OR_RETURN(const Recording rec, ReadRecording(o.dir));
  // OUT over the recording's header, events or one of its images would destroy the recording.
  const std::filesystem::path dir(o.dir);
  std::vector<NamedFile> inputs = {{"recording header", (dir / "recording.json").string()},
                                   {"recording events", (dir / "events.jsonl").string()},
                                   {"recording CAN log", (dir / "can.log").string()}};
  for (const nlohmann::json& e : rec.events) {
    if (e.value("type", "") != "image") continue;
    IDI_ASSIGN_OR_RETURN(std::string image, RecordedImagePath(rec, e));
    inputs.push_back({"recorded image", std::move(image)});
  }
  IDI_RETURN_IF_ERROR(CheckDistinctFiles(inputs, {{"OUT", o.out}}, "export-rawlog"));
  IDI_RETURN_IF_ERROR(CheckOutputFile(o.out, "export-rawlog: OUT"));
  // The rawlog is written beside its target and renamed over it: a link's file is the target (the
  // link stays), and a device or FIFO cannot be one.
  const std::string target = OutputTarget(o.out);
  std::error_code ec;
  const auto type = std::filesystem::status(target, ec).type();
  if (type != std::filesystem::file_type::regular && type != std::filesystem::file_type::not_found) {
    return InvalidArgument("export-rawlog: OUT " + o.out +
                           ": not a regular file (a rawlog is written beside it and "
                           "renamed over it)");
  }
  std::vector<RawlogFrame> frames;
  for (std::size_t k = 0; k < rec.events.size(); ++k) {
    const nlohmann::json& e = rec.events[k];
    if (e.value("type", "") != "image") continue;
    RawlogFrame f;
    IDI_ASSIGN_OR_RETURN(f.sensor_label,
                         StringField(e, "camera", "camera", fmt::format("{}/events.jsonl event {}", rec.dir, k + 1)));
    f.timestamp_unix_ns = UnixTimeOf(rec.header, e.value("t_ns", int64_t{0}));
    IDI_ASSIGN_OR_RETURN(f.image, LoadRecordedImage(rec, e));
    const auto cam = rec.header.cameras.find(f.sensor_label);
    if (cam != rec.header.cameras.end()) f.camera = cam->second;
    frames.push_back(std::move(f));
  }
  if (frames.empty()) return InvalidArgument(o.dir + ": the recording holds no images");
  IDI_RETURN_IF_ERROR(ExportRawlog(frames, target));
  spdlog::info("wrote {} images to {} (open with RawLogViewer or rawlog-edit --info)", frames.size(), o.out);
  return Status::Ok();
}
#endif

}  // namespace

void AddReplayCommands(CliApp& cli) {
  auto o = std::make_shared<ReplayOptions>();
  CLI::App* cmd = cli.AddCommand(
      &cli.app, "replay", "re-run a recorded run (docs/log-format.md) on this machine", [o] { return RunReplay(*o); });
  cmd->add_option("dir", o->dir, "recording folder")->required()->check(CLI::ExistingDirectory);
  cmd->add_flag("--json", o->json, "print the result as JSON");
#ifdef IDI_HAVE_RAWLOG
  auto e = std::make_shared<ExportOptions>();
  CLI::App* ex = cli.AddCommand(
      &cli.app, "export-rawlog", "write a recording's images as an MRPT rawlog", [e] { return RunExport(*e); });
  ex->add_option("dir", e->dir, "recording folder")->required()->check(CLI::ExistingDirectory);
  ex->add_option("out", e->out, "output .rawlog file")->required();
#endif
}

}  // namespace idi::workcell
