#include "workcell/procedures/ptu_files.h"

#include <fmt/format.h>
#include <yaml-cpp/yaml.h>

#include <cmath>
#include <filesystem>
#include <nlohmann/json.hpp>

#include "shared/plot/plot.h"
#include "shared/runtime/param_file.h"
#include "shared/util/atomic_file.h"
#include "workcell/procedures/calibration_files.h"

namespace idi::workcell {
namespace {

std::vector<ParamSpec> PtuPointSpecs() {
  return {{"point_x", Unit::kMillimetre, 0, "the stationary point, robot base frame"},
          {"point_y", Unit::kMillimetre, 0, ""},
          {"point_z", Unit::kMillimetre, 0, ""}};
}

std::vector<ParamSpec> PtuCameraSpecs(BiclopsSide side) {
  std::vector<ParamSpec> specs = PtuParamSpecs(side);
  const std::vector<ParamSpec> cam = CameraParamSpecs(BiclopsNominalCamera(side));
  specs.insert(specs.end(), cam.begin(), cam.end());
  return specs;
}

double ResidualRmsPx(const calib::PtuCalibrationResult& r) {
  double sum = 0;
  int n = 0;
  for (const auto& c : r.cameras) {
    sum += c.rms_px * c.rms_px * c.inliers;
    n += c.inliers;
  }
  return n > 0 ? std::sqrt(sum / n) : 0.0;
}

}  // namespace

Result<std::vector<calib::PtuObservation>> ReadPtuObservations(const std::string& path) {
  IDI_ASSIGN_OR_RETURN(const std::string text, ReadFile(path));
  return calib::ParsePtuObservationsCsv(text, path);
}

Status WritePtuObservations(const std::string& path, const std::vector<calib::PtuObservation>& observations) {
  return WriteFileAtomically(path, calib::FormatPtuObservationsCsv(observations));
}

Status WritePtuCalibration(const std::string& path, const calib::PtuCalibrationResult& r,
                           const calib::PtuValidation* validation) {
  for (const calib::PtuCameraCalibration& c : r.cameras) {
    const std::string where = path + " (" + BiclopsSideName(c.side) + " camera)";
    IDI_RETURN_IF_ERROR(CheckParamsWritable(c.model.ptu, where));
    IDI_RETURN_IF_ERROR(CheckParamsWritable(c.model.intrinsics, where));
  }
  YAML::Emitter e;
  e.SetDoublePrecision(12);
  e << YAML::BeginMap;
  e << YAML::Key << "model" << YAML::Value << kPtuCalibrationModel;
  for (const calib::PtuCameraCalibration& c : r.cameras) {
    e << YAML::Key << BiclopsSideName(c.side) << YAML::Value << YAML::BeginMap;
    e << YAML::Key << "image_width_px" << YAML::Value << c.model.width;
    e << YAML::Key << "image_height_px" << YAML::Value << c.model.height;
    EmitParamSet(e, c.model.ptu);
    EmitParamSet(e, c.model.intrinsics);
    e << YAML::EndMap;
  }
  ParamSet point(PtuPointSpecs());
  for (std::size_t i = 0; i < 3; ++i) {
    point.set_value(i, r.point_mm(static_cast<Eigen::Index>(i)));
    point.set_stddev(i, r.point_std_mm(static_cast<Eigen::Index>(i)));
  }
  EmitParamSet(e, point);
  e << YAML::Key << "statistics" << YAML::Value << YAML::BeginMap;
  int observations = 0;
  for (const auto& c : r.cameras) observations += c.observations;
  e << YAML::Key << "observations" << YAML::Value << observations;
  e << YAML::Key << "rejected" << YAML::Value << r.rejected;
  e << YAML::Key << "residual_rms_px" << YAML::Value << ResidualRmsPx(r);
  if (validation != nullptr) e << YAML::Key << "validation_rms_px" << YAML::Value << validation->rms_px;
  e << YAML::Key << "sigma0_px" << YAML::Value << std::sqrt(r.variance_factor);
  e << YAML::Key << "condition_number" << YAML::Value << r.condition_number;
  e << YAML::Key << "gauge" << YAML::Value << YAML::BeginSeq;
  for (const auto& g : r.gauge) e << fmt::format("fixed {}: {}", g.fixed_parameter, g.combination);
  e << YAML::EndSeq;
  e << YAML::Key << "held_fixed" << YAML::Value << YAML::Flow << r.held_fixed;
  e << YAML::EndMap;
  e << YAML::EndMap;
  if (!e.good()) return Internal(path + ": YAML emitter: " + e.GetLastError());
  return WriteFileAtomically(path, std::string(e.c_str()) + "\n");
}

Result<std::vector<calib::PtuCameraModel>> LoadPtuCalibration(const std::string& path) {
  IDI_ASSIGN_OR_RETURN(const std::string text, ReadFile(path));
  YAML::Node root;
  try {
    root = YAML::Load(text);
  } catch (const YAML::Exception& ex) {
    return ParseError(fmt::format("{}:{}: malformed YAML: {}", path, ex.mark.line + 1, ex.msg));
  }
  if (!root.IsMap()) return ParseError(path + ": expected a map");
  IDI_RETURN_IF_ERROR(CheckParamFileModel(root, {kPtuCalibrationModel}, path));
  std::vector<calib::PtuCameraModel> out;
  for (BiclopsSide side : {BiclopsSide::kLeft, BiclopsSide::kRight}) {
    const YAML::Node node = root[BiclopsSideName(side)];
    if (!node) continue;
    ParamFileOptions o;
    o.extra_keys = {"image_width_px", "image_height_px"};
    IDI_ASSIGN_OR_RETURN(const ParamSet all,
                         ParamSetFromYaml(node, PtuCameraSpecs(side), path + ": " + BiclopsSideName(side), o));
    calib::PtuCameraModel m = calib::PtuCameraModel::Nominal(side);
    m.ptu = all.Slice(0, kPtuParamCount);
    m.intrinsics = all.Slice(kPtuParamCount, kCameraParamCount);
    try {
      if (node["image_width_px"]) m.width = node["image_width_px"].as<int>();
      if (node["image_height_px"]) m.height = node["image_height_px"].as<int>();
    } catch (const YAML::Exception& ex) {
      return ParseError(fmt::format("{}:{}: image size: {}", path, ex.mark.line + 1, ex.msg));
    }
    if (m.width <= 0 || m.height <= 0) return InvalidArgument(path + ": image size must be positive");
    out.push_back(std::move(m));
  }
  if (out.empty()) return InvalidArgument(path + ": neither a 'left' nor a 'right' camera section");
  return out;
}

nlohmann::json PtuReportJson(const calib::PtuCalibrationResult& r, const calib::PtuValidation* v) {
  nlohmann::json j;
  j["point_mm"] = {r.point_mm.x(), r.point_mm.y(), r.point_mm.z()};
  j["point_std_mm"] = {r.point_std_mm.x(), r.point_std_mm.y(), r.point_std_mm.z()};
  j["initial_point_mm"] = {r.initial_point_mm.x(), r.initial_point_mm.y(), r.initial_point_mm.z()};
  j["residual_rms_px"] = ResidualRmsPx(r);
  j["validation_rms_px"] = v != nullptr ? nlohmann::json(v->rms_px) : nlohmann::json(nullptr);
  j["rms_definition"] = "root mean square of the u and v residual components";
  j["sigma0_px"] = std::sqrt(r.variance_factor);
  j["rejected"] = r.rejected;
  j["iterations"] = r.iterations;
  j["time_ms"] = r.time_ms;
  j["condition_number"] = r.condition_number;
  j["correlated_above_0_95"] = r.correlated;
  nlohmann::json gauge = nlohmann::json::array();
  for (const auto& g : r.gauge) {
    gauge.push_back({{"fixed", g.fixed_parameter}, {"combination", g.combination}, {"singular_value", g.singular_value}});
  }
  j["gauge"] = gauge;
  j["held_fixed"] = r.held_fixed;
  j["free_parameters"] = r.free_parameters;
  std::vector<double> sv(r.singular_values.data(), r.singular_values.data() + r.singular_values.size());
  j["singular_values_scaled"] = sv;
  nlohmann::json cams = nlohmann::json::array();
  nlohmann::json params;
  for (const auto& c : r.cameras) {
    nlohmann::json cj = {{"camera", BiclopsSideName(c.side)},
                         {"observations", c.observations},
                         {"inliers", c.inliers},
                         {"residual_rms_px", c.rms_px},
                         {"mean_error_px", c.mean_error_px},
                         {"max_error_px", c.max_error_px}};
    if (v != nullptr) {
      if (const auto* cv = v->Camera(c.side)) {
        cj["validation"] = {{"observations", cv->observations},
                            {"rms_px", cv->rms_px},
                            {"mean_error_px", cv->mean_error_px},
                            {"max_error_px", cv->max_error_px}};
      }
    }
    cams.push_back(cj);
    nlohmann::json pj = ParamsJson(c.model.ptu);
    pj.update(ParamsJson(c.model.intrinsics));
    params[BiclopsSideName(c.side)] = pj;
  }
  j["cameras"] = cams;
  j["params"] = params;
  return j;
}

Status SavePtuResidualHistograms(const std::string& dir, const calib::PtuCalibrationResult& r,
                                 const calib::PtuValidation* v) {
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) return IoError(dir + ": cannot create the plot folder: " + ec.message());
  for (const auto& c : r.cameras) {
    plot::Figure f;
    f.SetTitle(fmt::format("projection errors, {} camera (Fig. 6.{})", BiclopsSideName(c.side),
                           c.side == BiclopsSide::kLeft ? 3 : 4));
    f.x_axis().label = "pixel distance between the projected point and the spot (px)";
    f.y_axis().label = "images";
    std::vector<double> inliers;
    for (std::size_t i = 0; i < c.errors_px.size(); ++i) {
      if (c.inlier[i]) inliers.push_back(c.errors_px[i]);
    }
    IDI_RETURN_IF_ERROR(f.AddHistogram(inliers, 20,
                                       fmt::format("calibration images ({}, mean {:.3f} px)", inliers.size(),
                                                   c.mean_error_px),
                                       plot::kBlue));
    if (v != nullptr) {
      if (const auto* cv = v->Camera(c.side); cv != nullptr && !cv->errors_px.empty()) {
        IDI_RETURN_IF_ERROR(f.AddHistogram(
            cv->errors_px, 20,
            fmt::format("held-out images ({}, mean {:.3f} px)", cv->errors_px.size(), cv->mean_error_px),
            plot::kOrange));
      }
    }
    IDI_RETURN_IF_ERROR(f.SavePng(fmt::format("{}/ptu_{}_errors.png", dir, BiclopsSideName(c.side))));
  }
  return Status::Ok();
}

}  // namespace idi::workcell
