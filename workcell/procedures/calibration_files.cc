#include "workcell/procedures/calibration_files.h"

#include <fmt/format.h>
#include <yaml-cpp/yaml.h>

#include <cmath>
#include <cstdlib>
#include <nlohmann/json.hpp>
#include <sstream>

#include "shared/kinematics/rx130.h"
#include "shared/runtime/cli.h"
#include "shared/runtime/param_file.h"
#include "shared/util/atomic_file.h"
#include "shared/util/units.h"

namespace idi::workcell {
namespace {

std::string Trim(std::string s) {
  while (!s.empty() && (s.back() == '\r' || s.back() == ' ' || s.back() == '\t')) s.pop_back();
  std::size_t i = 0;
  while (i < s.size() && (s[i] == ' ' || s[i] == '\t')) ++i;
  return s.substr(i);
}

std::vector<std::string> Split(const std::string& line) {
  std::vector<std::string> out;
  std::stringstream ss(line);
  std::string item;
  while (std::getline(ss, item, ',')) out.push_back(Trim(item));
  if (!line.empty() && line.back() == ',') out.emplace_back();
  return out;
}

// Rows of numbers of a CSV with exactly `header`; each row with its line number.
Result<std::vector<std::pair<int, std::vector<double>>>> ReadCsv(const std::string& path, const std::string& header) {
  IDI_ASSIGN_OR_RETURN(const std::string text, ReadFile(path));
  std::stringstream ss(text);
  std::string line;
  int line_no = 0;
  std::vector<std::string> columns;
  std::vector<std::pair<int, std::vector<double>>> rows;
  while (std::getline(ss, line)) {
    ++line_no;
    line = Trim(line);
    if (line.empty()) continue;
    if (columns.empty()) {
      if (line != header) {
        return ParseError(path + ":" + std::to_string(line_no) + ": expected the header '" + header + "', got '" +
                          line.substr(0, 200) + "'");
      }
      columns = Split(line);
      continue;
    }
    const std::vector<std::string> cells = Split(line);
    if (cells.size() != columns.size()) {
      return ParseError(path + ":" + std::to_string(line_no) + ": expected " + std::to_string(columns.size()) +
                        " values, got " + std::to_string(cells.size()));
    }
    std::vector<double> values;
    for (std::size_t c = 0; c < cells.size(); ++c) {
      const char* begin = cells[c].c_str();
      char* end = nullptr;
      const double v = std::strtod(begin, &end);
      // Decimal only: strtod also reads hexadecimal ("0x10" is 16), "inf" and "nan".
      if (!IsDecimalNumber(cells[c]) || end != begin + cells[c].size() || !std::isfinite(v)) {
        return ParseError(path + ":" + std::to_string(line_no) + ": column '" + columns[c] + "': '" +
                          cells[c].substr(0, 40) + "' is not a finite decimal number");
      }
      values.push_back(v);
    }
    rows.emplace_back(line_no, std::move(values));
  }
  if (columns.empty()) return ParseError(path + ": empty file (expected the header '" + header + "')");
  return rows;
}

std::string Num(double v) {
  std::ostringstream s;
  s.precision(12);
  s << v;
  return s.str();
}

// How far past its range a joint reading may be. The controller stops each joint at its limit, so a
// reading well outside (9999 deg, radians read as degrees, another zero convention) is not one the arm
// can give: it is refused, not dropped later as an outlier. The margin allows for limits rounded on the
// data sheet. (Rx130JointLimits' controller-to-model offset is not yet checked on a real cell: if it is
// wrong, good readings are refused here, naming the joint and the range.)
constexpr double kJointReadingMarginDeg = 5.0;

// Refuses joint readings (degrees; columns `prefix`j1_deg..j6_deg) outside the RX-130's range by more
// than kJointReadingMarginDeg, naming the file, the line and the column.
Status CheckJointReadings(const std::string& path, int line, const std::string& prefix, const double* deg) {
  const JointLimits limits = Rx130JointLimits();
  for (std::size_t j = 0; j < static_cast<std::size_t>(kRx130Joints); ++j) {
    const double min_deg = RadToDeg(limits.min[j]), max_deg = RadToDeg(limits.max[j]);
    if (deg[j] >= min_deg - kJointReadingMarginDeg && deg[j] <= max_deg + kJointReadingMarginDeg) continue;
    return OutOfRange(fmt::format(
        "{}:{}: column '{}j{}_deg': {} deg is outside joint {}'s range [{:.1f}, {:.1f}] deg (by more than {:.0f} "
        "deg): not a reading the arm can give",
        path,
        line,
        prefix,
        j + 1,
        Num(deg[j]),
        j + 1,
        min_deg,
        max_deg,
        kJointReadingMarginDeg));
  }
  return Status::Ok();
}

void EmitStats(YAML::Emitter& e, const std::vector<std::pair<std::string, double>>& stats) {
  e << YAML::Key << "statistics" << YAML::Value << YAML::BeginMap;
  for (const auto& [k, v] : stats) e << YAML::Key << k << YAML::Value << v;
  e << YAML::EndMap;
}

// The YAML document in `path` (InvalidArgument naming the file when it does not parse).
Result<YAML::Node> LoadYamlFile(const std::string& path) {
  IDI_ASSIGN_OR_RETURN(const std::string text, ReadFile(path));
  try {
    return YAML::Load(text);
  } catch (const YAML::Exception& ex) {
    return InvalidArgument(path + ": " + ex.what());
  }
}

}  // namespace

Result<std::vector<calib::AimReading>> ReadRobotObservations(const std::string& path) {
  IDI_ASSIGN_OR_RETURN(const auto rows, ReadCsv(path, kRobotCsvHeader));
  std::vector<calib::AimReading> out;
  for (const auto& [line, v] : rows) {
    if (v[0] != 1.0 && v[0] != 2.0) {
      return ParseError(path + ":" + std::to_string(line) + ": column 'set' must be 1 or 2, got " + Num(v[0]));
    }
    IDI_RETURN_IF_ERROR(CheckJointReadings(path, line, "", &v[1]));
    calib::AimReading r;
    r.set = static_cast<int>(v[0]);
    r.q = JointsFromDeg({v[1], v[2], v[3], v[4], v[5], v[6]});
    r.row = line;
    out.push_back(r);
  }
  return out;
}

Status WriteRobotObservations(const std::string& path, const std::vector<calib::AimReading>& readings) {
  std::ostringstream s;
  s.precision(12);
  s << kRobotCsvHeader << "\n";
  for (const calib::AimReading& r : readings) {
    s << r.set;
    for (double d : JointsToDeg(r.q)) s << "," << d;
    s << "\n";
  }
  return WriteFileAtomically(path, s.str());
}

Result<std::vector<calib::RailReading>> ReadRailObservations(const std::string& path) {
  IDI_ASSIGN_OR_RETURN(const auto rows, ReadCsv(path, kRailCsvHeader));
  std::vector<calib::RailReading> out;
  for (const auto& [line, v] : rows) {
    IDI_RETURN_IF_ERROR(CheckJointReadings(path, line, "r1_", &v[0]));
    IDI_RETURN_IF_ERROR(CheckJointReadings(path, line, "r2_", &v[7]));
    calib::RailReading r;
    r.q1 = JointsFromDeg({v[0], v[1], v[2], v[3], v[4], v[5]});
    r.rail1_mm = v[6];
    r.q2 = JointsFromDeg({v[7], v[8], v[9], v[10], v[11], v[12]});
    r.rail2_mm = v[13];
    r.row = line;
    out.push_back(r);
  }
  return out;
}

Status WriteRailObservations(const std::string& path, const std::vector<calib::RailReading>& readings) {
  std::ostringstream s;
  s.precision(12);
  s << kRailCsvHeader << "\n";
  for (const calib::RailReading& r : readings) {
    bool first = true;
    for (double d : JointsToDeg(r.q1)) {
      s << (first ? "" : ",") << d;
      first = false;
    }
    s << "," << r.rail1_mm;
    for (double d : JointsToDeg(r.q2)) s << "," << d;
    s << "," << r.rail2_mm << "\n";
  }
  return WriteFileAtomically(path, s.str());
}

Status WriteRobotCalibration(const std::string& path,
                             const calib::RobotCalibrationResult& r,
                             const calib::RobotCalibrationData& data,
                             std::optional<unsigned> sim_seed) {
  if (const Status st = CheckParamsWritable(r.params, path); !st.ok()) {
    return Status(st.code(),
                  st.message() + fmt::format(" (Jacobian condition number {:.3g}; check the readings and the rail "
                                             "distance D, {} mm)",
                                             r.identifiability.condition_number,
                                             data.distance_mm));
  }
  YAML::Emitter e;
  e.SetDoublePrecision(12);
  e << YAML::BeginMap;
  e << YAML::Key << "model" << YAML::Value << kRobotCalibrationModel;
  if (sim_seed) e << YAML::Key << "sim_seed" << YAML::Value << *sim_seed;
  e << YAML::Key << "method" << YAML::Value << calib::MethodName(data.method);
  e << YAML::Key << "distance_mm" << YAML::Value << data.distance_mm;
  EmitParamSet(e, r.params);
  // The unknowns' correlation (in the order above), so the rail calibration can carry the arm's own
  // uncertainty into psi's (calib::CalibrateRail).
  const auto n = static_cast<Eigen::Index>(r.params.size());
  if (r.covariance.rows() == n && r.covariance.cols() == n && r.covariance.allFinite()) {
    const Eigen::VectorXd sd = r.covariance.diagonal().cwiseMax(0.0).cwiseSqrt();
    e << YAML::Key << "correlation" << YAML::Value << YAML::BeginSeq;
    for (Eigen::Index i = 0; i < n; ++i) {
      e << YAML::Flow << YAML::BeginSeq;
      for (Eigen::Index j = 0; j < n; ++j) {
        const double rho = sd(i) > 0 && sd(j) > 0 ? r.covariance(i, j) / (sd(i) * sd(j)) : (i == j ? 1.0 : 0.0);
        e << std::round(rho * 1e9) / 1e9;
      }
      e << YAML::EndSeq;
    }
    e << YAML::EndSeq;
  }
  EmitStats(e, {{"readings", static_cast<double>(data.readings.size())},
                {"readings_used", static_cast<double>(r.residuals.readings)},
                {"outliers", static_cast<double>(r.outliers.size())},
                {"rms_miss_mm", r.residuals.rms_miss_mm},
                {"median_miss_mm", r.residuals.median_miss_mm},
                {"max_miss_mm", r.residuals.max_miss_mm},
                {"rms_normalized", r.residuals.rms_normalized},
                {"variance_factor", r.residuals.variance_factor},
                {"condition_number", r.identifiability.condition_number},
                {"iterations", static_cast<double>(r.summary.iterations)},
                {"restarts", static_cast<double>(r.restarts)}});
  e << YAML::EndMap;
  if (!e.good()) return Internal(path + ": YAML emitter: " + e.GetLastError());
  return WriteFileAtomically(path, std::string(e.c_str()) + "\n");
}

Result<std::optional<unsigned>> RobotCalibrationSimSeed(const std::string& path) {
  IDI_ASSIGN_OR_RETURN(const YAML::Node root, LoadYamlFile(path));
  if (!root.IsMap() || !root["sim_seed"]) return std::optional<unsigned>();
  try {
    return std::optional<unsigned>(root["sim_seed"].as<unsigned>());
  } catch (const YAML::Exception&) {
    return InvalidArgument(path + ": sim_seed must be a whole number >= 0");
  }
}

Result<calib::ArmModel> LoadRobotCalibration(const std::string& path) {
  ParamFileOptions o;
  o.extra_keys = {"model", "comment", "method", "distance_mm", "statistics", "correlation", "sim_seed"};
  o.models = {kRobotCalibrationModel};
  IDI_ASSIGN_OR_RETURN(const ParamSet p, LoadParamFile(path, calib::RobotCalibrationSpecs(), o));
  calib::ArmModel m;
  m.robot = p.Slice(0, kRx130ParamCount);
  m.laser = p.Slice(kRx130ParamCount, kLaserParamCount);
  m.rail = p.Slice(kRx130ParamCount + kLaserParamCount + 3, kRailParamCount);
  // Optional (files written before it was added have none): the unknowns' correlation, which with
  // their std gives the arm model's covariance.
  IDI_ASSIGN_OR_RETURN(const YAML::Node root, LoadYamlFile(path));
  const YAML::Node corr = root["correlation"];
  if (!corr) return m;
  const std::size_t n = p.size();
  auto bad = [&](const std::string& what) { return InvalidArgument(path + ": correlation: " + what); };
  if (!corr.IsSequence() || corr.size() != n)
    return bad("must be " + std::to_string(n) + " rows of " + std::to_string(n) + " numbers");
  Eigen::MatrixXd rho(static_cast<Eigen::Index>(n), static_cast<Eigen::Index>(n));
  for (std::size_t i = 0; i < n; ++i) {
    if (!corr[i].IsSequence() || corr[i].size() != n)
      return bad("row " + std::to_string(i + 1) + " must have " + std::to_string(n) + " numbers");
    for (std::size_t j = 0; j < n; ++j) {
      double v = 0;
      try {
        v = corr[i][j].as<double>();
      } catch (const YAML::Exception&) {
        return bad("row " + std::to_string(i + 1) + ", column " + std::to_string(j + 1) + " is not a number");
      }
      if (!std::isfinite(v) || std::abs(v) > 1.0 + 1e-6 || (i == j && std::abs(v - 1.0) > 1e-6)) {
        return bad("row " + std::to_string(i + 1) + ", column " + std::to_string(j + 1) + ": " + FormatNumber(v) +
                   " is not a correlation (within [-1, 1], 1 on the diagonal)");
      }
      rho(static_cast<Eigen::Index>(i), static_cast<Eigen::Index>(j)) = v;
    }
  }
  if (!rho.isApprox(rho.transpose(), 1e-6)) return bad("is not symmetric");
  Eigen::MatrixXd cov(static_cast<Eigen::Index>(n), static_cast<Eigen::Index>(n));
  for (std::size_t i = 0; i < n; ++i) {
    if (!(std::isfinite(p.stddev(i)) && p.stddev(i) >= 0))
      return bad("needs every parameter's std (" + p.spec(i).Key() + " has none)");
    for (std::size_t j = 0; j < n; ++j) {
      cov(static_cast<Eigen::Index>(i), static_cast<Eigen::Index>(j)) =
          rho(static_cast<Eigen::Index>(i), static_cast<Eigen::Index>(j)) * p.stddev(i) * p.stddev(j);
    }
  }
  m.covariance = calib::ArmCovarianceFromUnknowns(cov);
  return m;
}

Status WriteRailCalibration(const std::string& path, const calib::RailCalibrationResult& r) {
  if (const Status st = CheckParamsWritable(r.psi, path); !st.ok()) {
    return Status(st.code(),
                  st.message() + fmt::format(" (Jacobian condition number {:.3g}; check the readings)",
                                             r.identifiability.condition_number));
  }
  YAML::Emitter e;
  e.SetDoublePrecision(12);
  e << YAML::BeginMap;
  e << YAML::Key << "model" << YAML::Value << kRailCalibrationModel;
  EmitParamSet(e, r.psi);
  EmitStats(e, {{"readings_used", static_cast<double>(r.readings_used)},
                {"outliers", static_cast<double>(r.outliers.size())},
                {"rms_distance_mm", r.rms_distance_mm},
                {"rms_normalized", r.rms_normalized},
                {"variance_factor", r.variance_factor},
                {"condition_number", r.identifiability.condition_number},
                {"iterations", static_cast<double>(r.summary.iterations)}});
  e << YAML::EndMap;
  if (!e.good()) return Internal(path + ": YAML emitter: " + e.GetLastError());
  return WriteFileAtomically(path, std::string(e.c_str()) + "\n");
}

Result<std::array<double, kRobotToRobotParamCount>> LoadRailCalibration(const std::string& path) {
  ParamFileOptions o;
  o.extra_keys = {"model", "comment", "statistics"};
  o.models = {kRailCalibrationModel};
  IDI_ASSIGN_OR_RETURN(const ParamSet p, LoadParamFile(path, RobotToRobotParamSpecs(), o));
  std::array<double, kRobotToRobotParamCount> psi{};
  for (std::size_t i = 0; i < psi.size(); ++i) psi[i] = p.value(i);
  return psi;
}

nlohmann::json ParamsJson(const ParamSet& set) {
  nlohmann::json j = nlohmann::json::object();
  for (std::size_t i = 0; i < set.size(); ++i) {
    nlohmann::json v = {{"value", set.file_value(i)}};
    if (!std::isnan(set.stddev(i))) v["std"] = std::isfinite(set.stddev(i)) ? nlohmann::json(set.file_stddev(i)) : nlohmann::json(nullptr);
    j[set.spec(i).Key()] = v;
  }
  return j;
}

Status WriteJson(const std::string& path, const nlohmann::json& j) { return WriteFileAtomically(path, j.dump(2) + "\n"); }

}  // namespace idi::workcell
