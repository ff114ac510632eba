#include "rmp/app/rmp_config.h"

#include <fmt/format.h>
#include <yaml-cpp/yaml.h>

#include <cmath>
#include <cstdint>
#include <functional>
#include <limits>
#include <map>
#include <set>

#include "shared/runtime/yaml_error.h"
#include "shared/sim/vehicle/vehicle_twin.h"
#include "shared/util/atomic_file.h"
#include "shared/util/units.h"

namespace idi::rmp {
namespace {

// Walks a YAML map: each key is handled by the field it names; unknown keys are errors.
class MapReader {
 public:
  MapReader(const YAML::Node& node, std::string source, std::string path)
      : node_(node), source_(std::move(source)), path_(std::move(path)) {}

  std::string Where(const YAML::Node& n) const { return source_ + ":" + std::to_string(n.Mark().line + 1); }
  std::string Key(const std::string& k) const { return path_.empty() ? k : path_ + "." + k; }

  // A finite number, in [lo, hi] when bounds are given (`why` says where they come from).
  void Number(const std::string& key,
              double* out,
              double lo = -std::numeric_limits<double>::infinity(),
              double hi = std::numeric_limits<double>::infinity(),
              const std::string& why = "") {
    handlers_[key] = [this, key, out, lo, hi, why](const YAML::Node& v) -> Status {
      double d = 0.0;
      try {
        d = v.as<double>();
      } catch (const YAML::Exception&) {
        return InvalidArgument(Where(v) + ": " + Key(key) + " must be a number");
      }
      if (!std::isfinite(d)) return InvalidArgument(Where(v) + ": " + Key(key) + " is not a finite number");
      if (!(d >= lo && d <= hi)) {
        return InvalidArgument(
            fmt::format("{}: {} = {} must be in [{:g}, {:g}] ({})", Where(v), Key(key), FormatNumber(d), lo, hi, why));
      }
      *out = d;
      return Status::Ok();
    };
  }
  void Int(const std::string& key, int* out) {
    handlers_[key] = [this, key, out](const YAML::Node& v) -> Status {
      try {
        *out = v.as<int>();
        return Status::Ok();
      } catch (const YAML::Exception&) {
        return InvalidArgument(Where(v) + ": " + Key(key) + " must be an integer");
      }
    };
  }
  // An integer in [lo, hi]; `why` says where the bounds come from.
  void Int(const std::string& key, int* out, int lo, int hi, const std::string& why) {
    handlers_[key] = [this, key, out, lo, hi, why](const YAML::Node& v) -> Status {
      long long n = 0;
      try {
        n = v.as<long long>();
      } catch (const YAML::Exception&) {
        return InvalidArgument(Where(v) + ": " + Key(key) + " must be an integer");
      }
      if (n < lo || n > hi) {
        return InvalidArgument(Where(v) + ": " + Key(key) + " = " + std::to_string(n) + " must be in [" +
                               std::to_string(lo) + ", " + std::to_string(hi) + "] (" + why + ")");
      }
      *out = static_cast<int>(n);
      return Status::Ok();
    };
  }
  void Uint64(const std::string& key, uint64_t* out) {
    handlers_[key] = [this, key, out](const YAML::Node& v) -> Status {
      try {
        *out = v.as<uint64_t>();
        return Status::Ok();
      } catch (const YAML::Exception&) {
        return InvalidArgument(Where(v) + ": " + Key(key) + " must be a non-negative integer");
      }
    };
  }
  void Bool(const std::string& key, bool* out) {
    handlers_[key] = [this, key, out](const YAML::Node& v) -> Status {
      try {
        *out = v.as<bool>();
        return Status::Ok();
      } catch (const YAML::Exception&) {
        return InvalidArgument(Where(v) + ": " + Key(key) + " must be true or false");
      }
    };
  }
  void String(const std::string& key, std::string* out) {
    handlers_[key] = [this, key, out](const YAML::Node& v) -> Status {
      if (!v.IsScalar()) return InvalidArgument(Where(v) + ": " + Key(key) + " must be a string");
      *out = v.as<std::string>();
      return Status::Ok();
    };
  }
  void Deg(const std::string& key, double* out_rad) {
    handlers_[key] = [this, key, out_rad](const YAML::Node& v) -> Status {
      try {
        const double d = v.as<double>();
        if (!std::isfinite(d)) return InvalidArgument(Where(v) + ": " + Key(key) + " is not a finite number");
        *out_rad = DegToRad(d);
        return Status::Ok();
      } catch (const YAML::Exception&) {
        return InvalidArgument(Where(v) + ": " + Key(key) + " must be a number");
      }
    };
  }
  void Custom(const std::string& key, std::function<Status(const YAML::Node&)> f) { handlers_[key] = std::move(f); }

  Status Run() {
    if (!node_ || node_.IsNull()) return Status::Ok();
    if (!node_.IsMap())
      return InvalidArgument(Where(node_) + ": " + (path_.empty() ? "the file" : path_) + " must be a map");
    std::set<std::string> seen;
    for (const auto& kv : node_) {
      if (!kv.first.IsScalar()) return InvalidArgument(Where(kv.first) + ": keys must be plain names");
      const std::string key = kv.first.as<std::string>();
      if (!seen.insert(key).second) return InvalidArgument(Where(kv.first) + ": key '" + Key(key) + "' given twice");
      auto it = handlers_.find(key);
      if (it == handlers_.end()) {
        std::string known;
        for (const auto& [k, h] : handlers_) known += (known.empty() ? "" : ", ") + k;
        return InvalidArgument(Where(kv.first) + ": unknown key '" + Key(key) + "' (known: " + known + ")");
      }
      IDI_RETURN_IF_ERROR(it->second(kv.second));
    }
    return Status::Ok();
  }

 private:
  YAML::Node node_;
  std::string source_, path_;
  std::map<std::string, std::function<Status(const YAML::Node&)>> handlers_;
};

// The largest image side the twin's renderer draws (sim::Render refuses larger cameras).
constexpr int kMaxImageSidePx = 16384;
// The largest image: the side bound alone let 16384x16384 through, 268 Mpx and 2 GB per camera in the
// perception's undistortion map (CV_32FC2) before the first frame.
constexpr int64_t kMaxImagePx = 16 * 1024 * 1024;

struct CameraPoseConfig {
  double x_m, y_m, z_m, yaw_rad, pitch_down_rad;
};

Status ReadRigCamera(
    const YAML::Node& n, const std::string& source, const std::string& path, RigCamera* cam, CameraPoseConfig* pose) {
  MapReader r(n, source, path);
  auto& p = cam->intrinsics.params;
  r.Number("fx_px", &p[kFx]);
  r.Number("fy_px", &p[kFy]);
  r.Number("cx_px", &p[kCx]);
  r.Number("cy_px", &p[kCy]);
  r.Number("k1", &p[kK1]);
  r.Number("k2", &p[kK2]);
  r.Number("p1", &p[kP1]);
  r.Number("p2", &p[kP2]);
  r.Number("k3", &p[kK3]);
  r.Number("x_m", &pose->x_m);
  r.Number("y_m", &pose->y_m);
  r.Number("z_m", &pose->z_m);
  r.Deg("yaw_deg", &pose->yaw_rad);
  r.Deg("pitch_down_deg", &pose->pitch_down_rad);
  return r.Run();
}

}  // namespace

bool LibcameraBuilt() {
#if IDI_RMP_LIBCAMERA
  return true;
#else
  return false;
#endif
}

const char* BackendName(Backend b) {
  switch (b) {
    case Backend::kSim:
      return "sim";
    case Backend::kReplay:
      return "replay";
    case Backend::kHardware:
      return "hardware";
  }
  return "?";
}

StereoRig DefaultStereoRig() {
  StereoRig rig;
  for (RigCamera* c : {&rig.left, &rig.right}) {
    c->intrinsics.width = 640;
    c->intrinsics.height = 480;
    c->intrinsics.params = {320.0, 320.0, 319.5, 239.5, 0, 0, 0, 0, 0};
    const double side = c == &rig.left ? 1.0 : -1.0;
    c->vehicle_from_camera = LookAheadCameraPose(0.0, side * 0.15, 1.2, 0.0, DegToRad(55.0));
  }
  return rig;
}

RmpConfig DefaultRmpConfig() {
  RmpConfig c;
  c.rig = DefaultStereoRig();
  c.driver.max_input_age_s = c.control.max_perception_age_s;
  return c;
}

Status RmpConfig::Check() const {
  IDI_RETURN_IF_ERROR(rig.Check().WithContext(source));
  IDI_RETURN_IF_ERROR(perception.Check().WithContext(source));
  IDI_RETURN_IF_ERROR(planner.Check().WithContext(source));
  IDI_RETURN_IF_ERROR(track.Check().WithContext(source));
  IDI_RETURN_IF_ERROR(control.Check().WithContext(source));
  IDI_RETURN_IF_ERROR(driver.Check().WithContext(source));
  IDI_RETURN_IF_ERROR(sim.Check().WithContext(source));
  if (backend == Backend::kHardware) {
    if (can_interface.empty()) return InvalidArgument(source + ": hardware.can.interface is empty");
    bool left = false, right = false;
    for (std::size_t i = 0; i < cameras.size(); ++i) {
      const CameraDeviceConfig& c = cameras[i];
      const std::string what = source + ": hardware.cameras: camera '" + c.name + "'";
      if (c.backend == "v4l2") {
        if (c.device.empty()) return InvalidArgument(what + " has no device (a capture node such as /dev/video0)");
      } else if (c.backend == "libcamera") {
        if (!LibcameraBuilt()) {
          return InvalidArgument(what + ": backend 'libcamera': this idi-rmp was built without libcamera " +
                                 "(install libcamera-dev and rebuild, or use backend: v4l2)");
        }
        if (c.device.empty())
          return InvalidArgument(what + " has no device (a libcamera camera id, or its index 0, 1, ...)");
      } else {
        return InvalidArgument(what + ": backend '" + c.backend + "' must be v4l2 or libcamera");
      }
      if (c.width <= 0 || c.height <= 0) {
        return InvalidArgument(what + ": width and height must be positive, got " + std::to_string(c.width) + "x" +
                               std::to_string(c.height));
      }
      if (!(c.frame_rate_hz >= 0 && c.frame_rate_hz <= 1000))
        return InvalidArgument(what + ": frame_rate_hz must be in [0, 1000]");
      // The perception undistorts with the rig's calibration: a camera delivering another size would
      // fail on every pair while the vehicle stands.
      const CameraModel& calibrated = c.name == "right" ? rig.right.intrinsics : rig.left.intrinsics;
      if (c.width != calibrated.width || c.height != calibrated.height) {
        return InvalidArgument(what + ": " + std::to_string(c.width) + "x" + std::to_string(c.height) +
                               " differs from the rig's calibration, " + std::to_string(calibrated.width) + "x" +
                               std::to_string(calibrated.height) + " (rig.width_px, rig.height_px)");
      }
      for (std::size_t j = 0; j < i; ++j) {
        if (cameras[j].backend == c.backend && cameras[j].device == c.device) {
          return InvalidArgument(what + " uses the same " + c.backend + " device '" + c.device + "' as camera '" +
                                 cameras[j].name + "'");
        }
      }
      left = left || c.name == "left";
      right = right || c.name == "right";
    }
    if (!left || !right) return InvalidArgument(source + ": hardware.cameras must name a 'left' and a 'right' camera");
  }
  return Status::Ok();
}

Result<RmpConfig> ParseRmpConfig(const std::string& text, const std::string& source) try {
  const YAML::Node root = YAML::Load(text);
  RmpConfig c = DefaultRmpConfig();
  c.source = source;
  MapReader top(root, source, "");
  std::string backend = "sim";
  top.String("backend", &backend);
  top.String("state_dir", &c.state_dir);
  top.Bool("record", &c.record);
  top.Custom("rig", [&](const YAML::Node& n) {
    CameraPoseConfig poses[2];
    for (int k = 0; k < 2; ++k) {
      const double side = k == 0 ? 1.0 : -1.0;
      poses[k] = {0.0, side * 0.15, 1.2, 0.0, DegToRad(55.0)};
    }
    int width = c.rig.left.intrinsics.width, height = c.rig.left.intrinsics.height;
    MapReader r(n, source, "rig");
    r.Custom("left", [&](const YAML::Node& v) { return ReadRigCamera(v, source, "rig.left", &c.rig.left, &poses[0]); });
    r.Custom("right",
             [&](const YAML::Node& v) { return ReadRigCamera(v, source, "rig.right", &c.rig.right, &poses[1]); });
    // The twin renders the images (and the perception undistorts them) whole: a size the renderer
    // refuses made the ground footprint and the undistortion maps allocate gigabytes first.
    const std::string why = "the twin renders images of 16 to " + std::to_string(kMaxImageSidePx) + " px a side";
    r.Int("width_px", &width, 16, kMaxImageSidePx, why);
    r.Int("height_px", &height, 16, kMaxImageSidePx, why);
    IDI_RETURN_IF_ERROR(r.Run());
    if (static_cast<int64_t>(width) * height > kMaxImagePx) {
      return InvalidArgument(r.Where(n) + ": rig.width_px x rig.height_px = " + std::to_string(width) + "x" +
                             std::to_string(height) + " must be at most " + std::to_string(kMaxImagePx) +
                             " px (16 Mpx) per camera");
    }
    RigCamera* cams[2] = {&c.rig.left, &c.rig.right};
    for (int k = 0; k < 2; ++k) {
      cams[k]->intrinsics.width = width;
      cams[k]->intrinsics.height = height;
      cams[k]->vehicle_from_camera =
          LookAheadCameraPose(poses[k].x_m, poses[k].y_m, poses[k].z_m, poses[k].yaw_rad, poses[k].pitch_down_rad);
    }
    return Status::Ok();
  });
  top.Custom("tape", [&](const YAML::Node& n) {
    MapReader r(n, source, "tape");
    r.Number("width_m", &c.perception.tape.tape_width_m);
    r.Bool("brighter", &c.perception.tape_brighter);
    IDI_RETURN_IF_ERROR(r.Run());
    // Caps the width tolerance (not a key of the file) at half the width.
    c.perception.tape.SetTapeWidth(c.perception.tape.tape_width_m);
    return Status::Ok();
  });
  top.Custom("perception", [&](const YAML::Node& n) {
    MapReader r(n, source, "perception");
    r.Number("max_range_m", &c.perception.max_range_m);
    r.Bool("parallel_views", &c.perception.parallel_views);
    return r.Run();
  });
  top.Custom("planner", [&](const YAML::Node& n) {
    MapReader r(n, source, "planner");
    PlannerOptions& p = c.planner;
    r.Number("cruise_speed_mps", &p.cruise_speed_mps);
    r.Number("max_speed_mps", &p.max_speed_mps);
    r.Number("max_accel_mps2", &p.max_accel_mps2);
    r.Number("max_decel_mps2", &p.max_decel_mps2);
    r.Number("max_yaw_rate_rps", &p.max_yaw_rate_rps);
    r.Number("max_yaw_accel_rps2", &p.max_yaw_accel_rps2);
    r.Number("max_lateral_accel_mps2", &p.max_lateral_accel_mps2);
    r.Number("corner_cut_m", &p.corner_cut_m);
    r.Number("max_corner_cut_m", &p.max_corner_cut_m);
    r.Number("command_latency_s", &p.command_latency_s);
    r.Number("response_time_constant_s", &p.response_time_constant_s);
    r.Bool("keep_track_in_view", &p.keep_track_in_view);
    return r.Run();
  });
  double rate_hz = 50.0;
  top.Custom("control", [&](const YAML::Node& n) {
    MapReader r(n, source, "control");
    r.Number("rate_hz", &rate_hz);
    r.Number("max_perception_age_s", &c.control.max_perception_age_s);
    r.Number("max_odometry_age_s", &c.control.max_odometry_age_s);
    r.Number("status_timeout_s", &c.driver.status_timeout_s);
    r.Number("track_lost_s", &c.control.track_lost_s);
    r.Number("finish_hold_s", &c.control.finish_hold_s);
    r.Number("max_run_s", &c.control.max_run_s);
    return r.Run();
  });
  top.Custom("rmp", [&](const YAML::Node& n) {
    MapReader r(n, source, "rmp");
    std::string model = "rmp200";
    r.String("model", &model);
    r.Number("velocity_scale", &c.driver.velocity_scale);
    r.Number("accel_scale", &c.driver.accel_scale);
    r.Number("turn_scale", &c.driver.turn_scale);
    r.Number("min_base_battery_v", &c.driver.min_base_battery_v);
    r.Bool("balance", &c.balance);
    IDI_RETURN_IF_ERROR(r.Run());
    auto m = ParseRmpModel(model);
    if (!m.ok()) return InvalidArgument(r.Where(n) + ": rmp.model: " + m.status().message());
    c.driver.codec.model = *m;
    return Status::Ok();
  });
  top.Custom("hardware", [&](const YAML::Node& n) {
    MapReader r(n, source, "hardware");
    r.Custom("can", [&](const YAML::Node& v) {
      MapReader cr(v, source, "hardware.can");
      cr.String("interface", &c.can_interface);
      return cr.Run();
    });
    r.Custom("cameras", [&](const YAML::Node& v) -> Status {
      if (!v.IsSequence()) return InvalidArgument(r.Where(v) + ": hardware.cameras must be a list");
      c.cameras.clear();
      for (std::size_t i = 0; i < v.size(); ++i) {
        CameraDeviceConfig cam;
        MapReader cr(v[i], source, "hardware.cameras[" + std::to_string(i) + "]");
        cr.String("name", &cam.name);
        cr.String("backend", &cam.backend);
        cr.String("device", &cam.device);
        cr.Int("width", &cam.width);
        cr.Int("height", &cam.height);
        cr.Number("frame_rate_hz", &cam.frame_rate_hz);
        IDI_RETURN_IF_ERROR(cr.Run());
        c.cameras.push_back(cam);
      }
      return Status::Ok();
    });
    return r.Run();
  });
  top.Custom("sim", [&](const YAML::Node& n) {
    MapReader r(n, source, "sim");
    SimOptions& s = c.sim;
    r.String("track", &c.sim_track);
    r.Bool("real_time", &c.sim_real_time);
    r.Number("camera_rate_hz", &s.camera_rate_hz);
    r.Number("camera_latency_s", &s.camera_latency_s);
    r.Uint64("seed", &s.seed);
    r.Number("calibration_pitch_error_deg", &s.calibration_pitch_error_deg);
    r.Number("calibration_height_error_m", &s.calibration_height_error_m);
    r.Number("left_wheel_scale_error", &s.left_wheel_scale_error);
    r.Number("right_wheel_scale_error", &s.right_wheel_scale_error);
    r.Number("slip_noise_m_per_sqrt_m", &s.slip_noise_m_per_sqrt_m);
    r.Custom("faults", [&](const YAML::Node& v) {
      MapReader fr(v, source, "sim.faults");
      SimFaults& f = s.faults;
      fr.String("frozen_camera", &f.frozen_camera);
      fr.Number("frozen_from_s", &f.frozen_from_s);
      fr.Number("frozen_to_s", &f.frozen_to_s);
      fr.Number("drop_probability", &f.drop_probability);
      fr.String("dead_camera", &f.dead_camera);
      fr.Number("dead_from_s", &f.dead_from_s);
      fr.Number("dead_to_s", &f.dead_to_s);
      fr.Number("rmp_silent_from_s", &f.rmp_silent_from_s);
      fr.Number("rmp_silent_to_s", &f.rmp_silent_to_s);
      fr.Number("integrators_missing_from_s", &f.integrators_missing_from_s);
      fr.Number("integrators_missing_to_s", &f.integrators_missing_to_s);
      fr.Number("bus_off_at_s", &f.bus_off_at_s);
      fr.Number("bus_off_duration_s", &f.bus_off_duration_s);
      fr.Number("battery_drop_at_s", &f.battery_drop_at_s);
      fr.Number("battery_drop_v",
                &f.battery_drop_v,
                0.0,
                sim::VehicleTwinOptions().base_battery_start_v,
                "volts the twin's powerbase battery loses; it starts full at the upper bound");
      fr.Number("stamp_glitch_at_s", &f.stamp_glitch_at_s);
      fr.Number("stamp_glitch_s", &f.stamp_glitch_s);
      fr.Custom("covered_m", [&](const YAML::Node& list) -> Status {
        if (!list.IsSequence())
          return InvalidArgument(fr.Where(list) + ": sim.faults.covered_m must be a list of [from, to]");
        f.covered_m.clear();
        for (std::size_t i = 0; i < list.size(); ++i) {
          try {
            if (!list[i].IsSequence() || list[i].size() != 2) throw YAML::Exception(list[i].Mark(), "");
            f.covered_m.emplace_back(list[i][0].as<double>(), list[i][1].as<double>());
            if (!std::isfinite(f.covered_m.back().first) || !std::isfinite(f.covered_m.back().second)) {
              return InvalidArgument(fr.Where(list[i]) + ": sim.faults.covered_m[" + std::to_string(i) +
                                     "] is not a finite [from, to] (metres along the track)");
            }
          } catch (const YAML::Exception&) {
            return InvalidArgument(fr.Where(list[i]) + ": sim.faults.covered_m[" + std::to_string(i) +
                                   "] must be [from, to]");
          }
        }
        return Status::Ok();
      });
      return fr.Run();
    });
    return r.Run();
  });
  top.Custom("replay", [&](const YAML::Node& n) {
    MapReader r(n, source, "replay");
    r.String("dir", &c.replay_dir);
    return r.Run();
  });
  IDI_RETURN_IF_ERROR(top.Run());
  if (backend == "sim")
    c.backend = Backend::kSim;
  else if (backend == "replay")
    c.backend = Backend::kReplay;
  else if (backend == "hardware")
    c.backend = Backend::kHardware;
  else
    return InvalidArgument(source + ": backend must be sim, replay or hardware, got '" + backend + "'");
  if (!(rate_hz >= 4.0 && rate_hz <= 100.0)) {
    return InvalidArgument(source + ": control.rate_hz = " + FormatNumber(rate_hz) +
                           " must be in [4, 100] (the RMP wants a command every 10-300 ms)");
  }
  c.driver.command_rate_hz = rate_hz;
  c.planner.control_period_s = 1.0 / rate_hz;
  c.driver.max_input_age_s = c.control.max_perception_age_s;
  if (c.balance) c.driver.operational_mode = OperationalMode::kBalance;
  c.sim.balance_mode = c.balance;
  IDI_RETURN_IF_ERROR(c.Check());
  return c;
} catch (const YAML::Exception& e) {
  return YamlError(source, e);
}

Result<RmpConfig> LoadRmpConfig(const std::string& path) {
  auto text = ReadFile(path);
  if (!text.ok()) return NotFound(path + ": cannot read the configuration (" + text.status().message() + ")");
  return ParseRmpConfig(*text, path);
}

}  // namespace idi::rmp
