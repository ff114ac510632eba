#include "workcell/service/workcell_config.h"

#include <yaml-cpp/yaml.h>

#include <set>

#include "shared/runtime/yaml_error.h"
#include "shared/util/atomic_file.h"

namespace idi::workcell {
namespace {

std::string At(const std::string& where, const YAML::Node& n) {
  return n.Mark().line >= 0 ? where + ":" + std::to_string(n.Mark().line + 1) : where;
}

Status OnlyKeys(const YAML::Node& map, const std::set<std::string>& allowed, const std::string& where,
                const std::string& section) {
  if (!map.IsMap()) return InvalidArgument(At(where, map) + ": '" + section + "' must be a map");
  std::set<std::string> seen;
  for (const auto& kv : map) {
    const std::string key = kv.first.as<std::string>();
    if (!seen.insert(key).second) {
      return InvalidArgument(At(where, kv.first) + ": key '" + (section.empty() ? "" : section + ".") + key +
                             "' given twice");
    }
    if (allowed.count(key) == 0) {
      return InvalidArgument(At(where, kv.first) + ": unknown key '" + (section.empty() ? "" : section + ".") + key + "'");
    }
  }
  return Status::Ok();
}

template <typename T>
Status Read(const YAML::Node& map, const std::string& key, const std::string& where, const std::string& section, T* out) {
  const YAML::Node n = map[key];
  if (!n) return Status::Ok();
  try {
    *out = n.as<T>();
  } catch (const YAML::Exception&) {
    return InvalidArgument(At(where, n) + ": key '" + (section.empty() ? "" : section + ".") + key + "' has the wrong type");
  }
  return Status::Ok();
}

Result<SerialEndpoint> ReadSerial(const YAML::Node& n, const std::string& where, const std::string& section) {
  IDI_RETURN_IF_ERROR(OnlyKeys(n, {"name", "device", "baud"}, where, section));
  SerialEndpoint e;
  IDI_RETURN_IF_ERROR(Read(n, "name", where, section, &e.name));
  IDI_RETURN_IF_ERROR(Read(n, "device", where, section, &e.device));
  IDI_RETURN_IF_ERROR(Read(n, "baud", where, section, &e.baud));
  if (e.device.empty()) return InvalidArgument(At(where, n) + ": '" + section + ".device' is required");
  if (e.baud <= 0) return InvalidArgument(At(where, n) + ": '" + section + ".baud' must be positive");
  return e;
}

}  // namespace

Result<WorkcellConfig> ParseWorkcellConfig(const std::string& text, const std::string& where) try {
  const YAML::Node root = YAML::Load(text);
  if (!root || root.IsNull()) return InvalidArgument(where + ": empty configuration");
  IDI_RETURN_IF_ERROR(
      OnlyKeys(root, {"backend", "state_dir", "control", "calibration", "sim", "hardware", "exit_when_idle"}, where, ""));
  WorkcellConfig c;
  IDI_RETURN_IF_ERROR(Read(root, "backend", where, "", &c.backend));
  if (c.backend != "sim" && c.backend != "hardware") {
    return InvalidArgument(At(where, root["backend"]) + ": backend '" + c.backend + "' (expected sim or hardware)");
  }
  IDI_RETURN_IF_ERROR(Read(root, "state_dir", where, "", &c.state_dir));
  IDI_RETURN_IF_ERROR(Read(root, "exit_when_idle", where, "", &c.exit_when_idle));
  if (root["control"]) {
    IDI_RETURN_IF_ERROR(OnlyKeys(root["control"], {"socket", "group"}, where, "control"));
    IDI_RETURN_IF_ERROR(Read(root["control"], "socket", where, "control", &c.control_socket));
    IDI_RETURN_IF_ERROR(Read(root["control"], "group", where, "control", &c.control_group));
  }
  if (root["calibration"]) {
    const YAML::Node cal = root["calibration"];
    IDI_RETURN_IF_ERROR(OnlyKeys(cal, {"max_age_days", "recalibrate_when_stale"}, where, "calibration"));
    IDI_RETURN_IF_ERROR(Read(cal, "max_age_days", where, "calibration", &c.calibration_max_age_days));
    IDI_RETURN_IF_ERROR(Read(cal, "recalibrate_when_stale", where, "calibration", &c.recalibrate_when_stale));
    if (!(c.calibration_max_age_days > 0)) {
      return InvalidArgument(At(where, cal) + ": 'calibration.max_age_days' must be positive");
    }
  }
  if (root["sim"]) {
    IDI_RETURN_IF_ERROR(OnlyKeys(root["sim"], {"seed", "day", "pace"}, where, "sim"));
    IDI_RETURN_IF_ERROR(Read(root["sim"], "seed", where, "sim", &c.sim_seed));
    IDI_RETURN_IF_ERROR(Read(root["sim"], "pace", where, "sim", &c.sim_pace));
    if (!(c.sim_pace >= 0 && c.sim_pace <= 100)) {
      return InvalidArgument(At(where, root["sim"]["pace"]) + ": 'sim.pace' must be in [0, 100] (wall seconds per simulated second)");
    }
    if (const YAML::Node day = root["sim"]["day"]) {
      if (!day.IsSequence()) return InvalidArgument(At(where, day) + ": 'sim.day' must be a list of objects");
      for (const YAML::Node& n : day) {
        const std::string name = n.IsScalar() ? n.as<std::string>() : std::string();
        if (name != "box" && name != "prism" && name != "bracket" && name != "cylinder") {
          return InvalidArgument(At(where, n) + ": 'sim.day' entries are box, prism, bracket or cylinder");
        }
        c.sim_day.push_back(name);
      }
    }
  }
  if (root["hardware"]) {
    const YAML::Node hw = root["hardware"];
    IDI_RETURN_IF_ERROR(OnlyKeys(hw, {"arms", "ptus", "hand", "cameras"}, where, "hardware"));
    for (const auto& a : hw["arms"]) {
      IDI_RETURN_IF_ERROR(OnlyKeys(a, {"name", "host", "port"}, where, "hardware.arms"));
      ArmEndpoint e;
      IDI_RETURN_IF_ERROR(Read(a, "name", where, "hardware.arms", &e.name));
      IDI_RETURN_IF_ERROR(Read(a, "host", where, "hardware.arms", &e.host));
      IDI_RETURN_IF_ERROR(Read(a, "port", where, "hardware.arms", &e.port));
      if (e.host.empty() || e.port <= 0 || e.port > 65535) {
        return InvalidArgument(At(where, a) + ": 'hardware.arms' entries need a host and a port in 1..65535");
      }
      c.arms.push_back(e);
    }
    for (const auto& p : hw["ptus"]) {
      IDI_ASSIGN_OR_RETURN(SerialEndpoint e, ReadSerial(p, where, "hardware.ptus"));
      c.ptus.push_back(e);
    }
    if (hw["hand"]) {
      IDI_ASSIGN_OR_RETURN(c.hand, ReadSerial(hw["hand"], where, "hardware.hand"));
    }
    for (const auto& cam : hw["cameras"]) {
      IDI_RETURN_IF_ERROR(
          OnlyKeys(cam, {"name", "backend", "device", "width", "height", "exposure_us"}, where, "hardware.cameras"));
      CameraEndpoint e;
      IDI_RETURN_IF_ERROR(Read(cam, "name", where, "hardware.cameras", &e.name));
      IDI_RETURN_IF_ERROR(Read(cam, "backend", where, "hardware.cameras", &e.backend));
      IDI_RETURN_IF_ERROR(Read(cam, "device", where, "hardware.cameras", &e.device));
      IDI_RETURN_IF_ERROR(Read(cam, "width", where, "hardware.cameras", &e.width));
      IDI_RETURN_IF_ERROR(Read(cam, "height", where, "hardware.cameras", &e.height));
      IDI_RETURN_IF_ERROR(Read(cam, "exposure_us", where, "hardware.cameras", &e.exposure_us));
      if (e.backend != "v4l2" && e.backend != "mrpt") {
        return InvalidArgument(At(where, cam) + ": camera backend '" + e.backend + "' (expected v4l2 or mrpt)");
      }
      if (e.width < 16 || e.width > 8192 || e.height < 16 || e.height > 8192) {
        return InvalidArgument(At(where, cam) + ": 'hardware.cameras' width and height must be in 16..8192, got " +
                               std::to_string(e.width) + " x " + std::to_string(e.height));
      }
      if (!(e.exposure_us >= 0 && e.exposure_us <= 10e6)) {
        return InvalidArgument(At(where, cam) +
                               ": 'hardware.cameras.exposure_us' must be in [0, 1e7] (0: the camera's own)");
      }
      c.cameras.push_back(e);
    }
  }
  if (c.backend == "hardware" && (c.arms.size() != 2 || c.ptus.size() != 2 || c.hand.device.empty() ||
                                  c.cameras.size() != 2)) {
    return InvalidArgument(where + ": backend 'hardware' needs hardware.arms (2), hardware.ptus (2), hardware.hand and "
                           "hardware.cameras (2)");
  }
  return c;
} catch (const YAML::Exception& e) {
  return YamlError(where, e);
}

Result<WorkcellConfig> LoadWorkcellConfig(const std::string& path) {
  IDI_ASSIGN_OR_RETURN(const std::string text, ReadFile(path));
  return ParseWorkcellConfig(text, path);
}

}  // namespace idi::workcell
