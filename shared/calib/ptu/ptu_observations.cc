#include "shared/calib/ptu/ptu_observations.h"

#include <fmt/format.h>

#include <array>
#include <charconv>
#include <cmath>
#include <map>
#include <tuple>

namespace idi::calib {
namespace {

constexpr std::array<std::string_view, 11> kPtuCsvColumns = {
    "camera", "x_mm", "y_mm", "z_mm", "alpha_deg", "beta_deg", "gamma_deg", "pan_deg", "tilt_deg", "u_px", "v_px"};

std::string_view TrimCsvField(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t')) s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t' || s.back() == '\r')) s.remove_suffix(1);
  return s;
}

std::vector<std::string_view> SplitCsvLine(std::string_view line) {
  std::vector<std::string_view> out;
  std::size_t start = 0;
  while (true) {
    const std::size_t comma = line.find(',', start);
    out.push_back(TrimCsvField(line.substr(start, comma == std::string_view::npos ? line.npos : comma - start)));
    if (comma == std::string_view::npos) break;
    start = comma + 1;
  }
  return out;
}

// A finite number filling the whole field; the message says what was wrong.
Result<double> ParseCsvNumber(std::string_view field, std::string_view column, const std::string& where, int line) {
  if (field.empty()) {
    if (column == "u_px" || column == "v_px") {
      return InvalidArgument(fmt::format("{}:{}: {} is empty: the spot was not found in this image; remove the row "
                                         "or re-take the image",
                                         where, line, column));
    }
    return ParseError(fmt::format("{}:{}: {} is empty", where, line, column));
  }
  double v = 0;
  const char* first = field.data();
  const char* last = field.data() + field.size();
  if (*first == '+') ++first;
  const auto [ptr, ec] = std::from_chars(first, last, v);
  if (ec != std::errc() || ptr != last) {
    return ParseError(fmt::format("{}:{}: {} = '{}' is not a number", where, line, column, field));
  }
  if (!std::isfinite(v)) {
    return ParseError(fmt::format("{}:{}: {} = '{}' is not finite", where, line, column, field));
  }
  return v;
}

std::string ObservationPlace(const PtuObservation& o, std::size_t index, const std::string& where) {
  if (o.source_line > 0) return fmt::format("{}:{}", where, o.source_line);
  return fmt::format("{}: observation {}", where, index);
}

}  // namespace

Status PtuRange::Check() const {
  if (!(pan_min_rad < pan_max_rad) || !(tilt_min_rad < tilt_max_rad) || !std::isfinite(pan_min_rad) ||
      !std::isfinite(pan_max_rad) || !std::isfinite(tilt_min_rad) || !std::isfinite(tilt_max_rad)) {
    return InvalidArgument("PtuRange: need finite limits with min < max for pan and tilt");
  }
  return Status::Ok();
}

Result<std::vector<PtuObservation>> ParsePtuObservationsCsv(std::string_view text, const std::string& where) {
  std::vector<PtuObservation> out;
  std::array<int, kPtuCsvColumns.size()> column_of{};
  column_of.fill(-1);
  std::size_t header_fields = 0;
  bool have_header = false;
  int line_no = 0;
  std::size_t pos = 0;
  while (pos <= text.size()) {
    const std::size_t end = text.find('\n', pos);
    const std::string_view raw = text.substr(pos, end == std::string_view::npos ? text.npos : end - pos);
    pos = end == std::string_view::npos ? text.size() + 1 : end + 1;
    ++line_no;
    const std::string_view line = TrimCsvField(raw);
    if (line.empty() || line.front() == '#') continue;
    const std::vector<std::string_view> fields = SplitCsvLine(line);
    if (!have_header) {
      for (std::size_t i = 0; i < fields.size(); ++i) {
        bool known = false;
        for (std::size_t c = 0; c < kPtuCsvColumns.size(); ++c) {
          if (fields[i] == kPtuCsvColumns[c]) {
            if (column_of[c] >= 0) {
              return ParseError(fmt::format("{}:{}: column '{}' appears twice in the header", where, line_no, fields[i]));
            }
            column_of[c] = static_cast<int>(i);
            known = true;
          }
        }
        if (!known) {
          return ParseError(fmt::format("{}:{}: unknown column '{}' (expected {})", where, line_no, fields[i],
                                        fmt::join(kPtuCsvColumns, ",")));
        }
      }
      for (std::size_t c = 0; c < kPtuCsvColumns.size(); ++c) {
        if (column_of[c] < 0) {
          return ParseError(fmt::format("{}:{}: the header lacks column '{}' (expected {})", where, line_no,
                                        kPtuCsvColumns[c], fmt::join(kPtuCsvColumns, ",")));
        }
      }
      header_fields = fields.size();
      have_header = true;
      continue;
    }
    if (fields.size() != header_fields) {
      return ParseError(
          fmt::format("{}:{}: {} fields where the header has {}", where, line_no, fields.size(), header_fields));
    }
    PtuObservation o;
    o.source_line = line_no;
    const std::string_view camera = fields[static_cast<std::size_t>(column_of[0])];
    if (camera == "left") {
      o.camera = BiclopsSide::kLeft;
    } else if (camera == "right") {
      o.camera = BiclopsSide::kRight;
    } else {
      return ParseError(fmt::format("{}:{}: camera = '{}' (expected left or right)", where, line_no, camera));
    }
    std::array<double, kPtuCsvColumns.size()> v{};
    for (std::size_t c = 1; c < kPtuCsvColumns.size(); ++c) {
      IDI_ASSIGN_OR_RETURN(v[c], ParseCsvNumber(fields[static_cast<std::size_t>(column_of[c])], kPtuCsvColumns[c],
                                                where, line_no));
    }
    o.tcf = {v[1], v[2], v[3], DegToRad(v[4]), DegToRad(v[5]), DegToRad(v[6])};
    o.pan_rad = DegToRad(v[7]);
    o.tilt_rad = DegToRad(v[8]);
    o.pixel_px = Vec2d(v[9], v[10]);
    out.push_back(o);
  }
  if (!have_header) {
    return ParseError(fmt::format("{}: no header line (expected {})", where, fmt::join(kPtuCsvColumns, ",")));
  }
  return out;
}

std::string FormatPtuObservationsCsv(const std::vector<PtuObservation>& observations) {
  std::string out = fmt::format("{}\n", fmt::join(kPtuCsvColumns, ","));
  for (const PtuObservation& o : observations) {
    out += fmt::format("{},{:.17g},{:.17g},{:.17g},{:.17g},{:.17g},{:.17g},{:.17g},{:.17g},{:.17g},{:.17g}\n",
                       BiclopsSideName(o.camera), o.tcf.x_mm, o.tcf.y_mm, o.tcf.z_mm, RadToDeg(o.tcf.alpha_rad),
                       RadToDeg(o.tcf.beta_rad), RadToDeg(o.tcf.gamma_rad), RadToDeg(o.pan_rad), RadToDeg(o.tilt_rad),
                       o.pixel_px.x(), o.pixel_px.y());
  }
  return out;
}

Status CheckPtuObservations(const std::vector<PtuObservation>& observations, const PtuRange& range,
                            const std::string& where) {
  IDI_RETURN_IF_ERROR(range.Check());
  // Key of one image: camera, arm pose and PTU readings (rounded far below any real difference).
  using ImageKey = std::tuple<int, long long, long long, long long, long long, long long, long long, long long, long long>;
  const auto q = [](double v) { return std::llround(v * 1e6); };
  std::map<ImageKey, std::size_t> seen;
  for (std::size_t i = 0; i < observations.size(); ++i) {
    const PtuObservation& o = observations[i];
    const std::string place = ObservationPlace(o, i, where);
    const double values[] = {o.tcf.x_mm,      o.tcf.y_mm,      o.tcf.z_mm, o.tcf.alpha_rad, o.tcf.beta_rad,
                             o.tcf.gamma_rad, o.pan_rad,       o.tilt_rad, o.pixel_px.x(),  o.pixel_px.y()};
    for (double v : values) {
      if (!std::isfinite(v)) return InvalidArgument(place + ": a value is not finite");
    }
    if (!range.Contains(o.pan_rad, range.tilt_min_rad)) {
      return OutOfRange(fmt::format("{}: pan = {:.4f} deg is outside the PTU's range [{:.4f}, {:.4f}] deg", place,
                                    RadToDeg(o.pan_rad), RadToDeg(range.pan_min_rad), RadToDeg(range.pan_max_rad)));
    }
    if (!range.Contains(range.pan_min_rad, o.tilt_rad)) {
      return OutOfRange(fmt::format("{}: tilt = {:.4f} deg is outside the PTU's range [{:.4f}, {:.4f}] deg", place,
                                    RadToDeg(o.tilt_rad), RadToDeg(range.tilt_min_rad), RadToDeg(range.tilt_max_rad)));
    }
    const ImageKey key{static_cast<int>(o.camera), q(o.tcf.x_mm),      q(o.tcf.y_mm),  q(o.tcf.z_mm),
                       q(o.tcf.alpha_rad),          q(o.tcf.beta_rad), q(o.tcf.gamma_rad), q(o.pan_rad),
                       q(o.tilt_rad)};
    const auto [it, inserted] = seen.emplace(key, i);
    if (!inserted) {
      const PtuObservation& first = observations[it->second];
      return InvalidArgument(fmt::format(
          "{}: a second spot in the same {} image as {} (at ({:.2f}, {:.2f}) and ({:.2f}, {:.2f}) px): the "
          "calibration needs exactly one bright spot per image (§6.4.3); remove the reflection or second source",
          place, BiclopsSideName(o.camera), ObservationPlace(first, it->second, where), first.pixel_px.x(),
          first.pixel_px.y(), o.pixel_px.x(), o.pixel_px.y()));
    }
  }
  return Status::Ok();
}

std::vector<PtuObservation> SelectCamera(const std::vector<PtuObservation>& observations, BiclopsSide camera) {
  std::vector<PtuObservation> out;
  for (const PtuObservation& o : observations) {
    if (o.camera == camera) out.push_back(o);
  }
  return out;
}

}  // namespace idi::calib
