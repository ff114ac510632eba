#include "shared/replay/recording.h"

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <opencv2/imgcodecs.hpp>
#include <utility>

#include "shared/plot/png_file.h"
#include "shared/util/atomic_file.h"

namespace idi {
namespace fs = std::filesystem;

namespace {

nlohmann::json HeaderJson(const RecordingHeader& h) {
  nlohmann::json j;
  j["format"] = "idi-recording";
  j["version"] = kRecordingVersion;
  j["kind"] = h.kind;
  j["created_unix_ns"] = h.created_unix_ns;
  j["created_clock_ns"] = h.created_clock_ns;
  j["cameras"] = nlohmann::json::object();
  for (const auto& [name, c] : h.cameras) {
    j["cameras"][name] = {{"width", c.width}, {"height", c.height}, {"params", c.params}};
  }
  j["meta"] = h.meta;
  return j;
}

}  // namespace

Result<RecordingWriter> RecordingWriter::Create(const std::string& dir, const RecordingHeader& header) {
  std::error_code ec;
  if (fs::exists(dir, ec) && !fs::is_empty(dir, ec)) {
    return InvalidArgument(dir + ": a recording folder must be new or empty");
  }
  fs::create_directories(fs::path(dir) / "images", ec);
  if (ec) return IoError(dir + ": cannot create: " + ec.message());
  IDI_RETURN_IF_ERROR(
      WriteFileAtomically((fs::path(dir) / "recording.json").string(), HeaderJson(header).dump(2) + "\n"));
  RecordingWriter w;
  w.dir_ = dir;
  w.header_ = header;
  w.out_ = std::make_unique<std::ofstream>(fs::path(dir) / "events.jsonl", std::ios::out | std::ios::trunc);
  if (!*w.out_) return IoError(dir + "/events.jsonl: cannot open for writing");
  return w;
}

Status RecordingWriter::Add(int64_t t_ns, nlohmann::json event) {
  if (!event.is_object() || !event.contains("type") || !event["type"].is_string()) {
    return InvalidArgument("recording event needs a string 'type'");
  }
  event["t_ns"] = t_ns;
  *out_ << event.dump() << '\n';
  out_->flush();
  if (!*out_) return IoError(dir_ + "/events.jsonl: write failed");
  ++events_;
  return Status::Ok();
}

Status RecordingWriter::AddImage(int64_t t_ns, const std::string& camera, uint64_t seq, const cv::Mat& image) {
  if (image.empty() || image.depth() != CV_8U || (image.channels() != 1 && image.channels() != 3)) {
    return InvalidArgument("recording: image from " + camera + " is empty or not 8-bit gray/BGR");
  }
  char name[64];
  std::snprintf(name, sizeof(name), "%06llu_", static_cast<unsigned long long>(seq));
  const std::string rel = std::string("images/") + name + camera + ".png";
  const std::string path = (fs::path(dir_) / rel).string();
  // A sequence number seen twice (a camera that counted from 0 again) must not replace a recorded frame.
  std::error_code ec;
  if (fs::exists(path, ec))
    return FailedPrecondition(path + ": already recorded (frame sequence " + std::to_string(seq) + " of " + camera +
                              " seen twice); not overwritten");
  if (!cv::imwrite(path, image)) return IoError(path + ": cannot write the image");
  return Add(t_ns, {{"type", "image"}, {"camera", camera}, {"seq", seq}, {"file", rel}});
}

Status RecordingWriter::Finish(const nlohmann::json& final_meta) {
  header_.meta = final_meta;
  out_->flush();
  return WriteFileAtomically((fs::path(dir_) / "recording.json").string(), HeaderJson(header_).dump(2) + "\n");
}

namespace {

// An integer >= 0 (JSON text reads one as unsigned, code that builds JSON may give it signed).
bool IsCount(const nlohmann::json& v) {
  if (v.is_number_float()) {  // 12.0: what replay has always read as 12
    const double d = v.get<double>();
    return d >= 0 && d < 9007199254740992.0 && std::floor(d) == d;
  }
  return v.is_number_unsigned() || (v.is_number_integer() && v.get<int64_t>() >= 0);
}

// The header's fields beyond format and version (throws nlohmann::json::exception on a wrong type).
Status ReadHeaderFields(const nlohmann::json& h, const std::string& header_path, RecordingHeader* header) {
  header->kind = h.value("kind", "");
  header->created_unix_ns = h.value("created_unix_ns", int64_t{0});
  header->created_clock_ns = h.value("created_clock_ns", int64_t{0});
  header->meta = h.value("meta", nlohmann::json::object());
  // Free-form, but an object, and `points` (the recorded run's count, which replay compares) a count.
  if (header->meta.is_null()) header->meta = nlohmann::json::object();
  if (!header->meta.is_object()) {
    return ParseError(header_path + ": meta must be an object, got " + header->meta.dump());
  }
  if (header->meta.contains("points") && !IsCount(header->meta["points"])) {
    return ParseError(header_path + ": meta.points must be a count (an integer >= 0), got " +
                      header->meta["points"].dump());
  }
  if (h.contains("cameras")) {
    for (const auto& [name, c] : h["cameras"].items()) {
      CameraModel m;
      if (!c.contains("params") || !c["params"].is_array() || c["params"].size() != kCameraParamCount) {
        return ParseError(header_path + ": camera '" + name + "' needs 9 params");
      }
      m.width = c.value("width", 0);
      m.height = c.value("height", 0);
      for (int k = 0; k < kCameraParamCount; ++k)
        m.params[static_cast<std::size_t>(k)] = c["params"][static_cast<std::size_t>(k)].get<double>();
      header->cameras[name] = m;
    }
  }
  return Status::Ok();
}

// What an event may not hold, beyond its type and t_ns being a string and an integer: a t_ns whose
// wall-clock time (UnixTimeOf) does not fit in int64, and in an image event a seq that is not a frame
// number, a file outside the recording, or a frame or file seen before. Empty when the event is fine.
class EventChecker {
 public:
  explicit EventChecker(const RecordingHeader& header) : header_(header) {}

  std::string Check(const nlohmann::json& e, int line_no) {
    const nlohmann::json& t = e["t_ns"];
    int64_t since_creation = 0, unix_ns = 0;
    if ((t.is_number_unsigned() && t.get<uint64_t>() > static_cast<uint64_t>(std::numeric_limits<int64_t>::max())) ||
        __builtin_sub_overflow(t.get<int64_t>(), header_.created_clock_ns, &since_creation) ||
        __builtin_add_overflow(header_.created_unix_ns, since_creation, &unix_ns)) {
      return "t_ns " + t.dump() +
             " is not a time of this recording (created_unix_ns + t_ns - created_clock_ns "
             "does not fit in 64 bits)";
    }
    if (e["type"] != "image") return "";
    if (!e.contains("file") || !e["file"].is_string()) return "an image event needs its file name (a string)";
    const std::filesystem::path file(e["file"].get<std::string>());
    bool inside = !file.empty() && file.is_relative();
    for (const auto& part : file) inside = inside && part != "..";
    if (!inside) {
      return "an image event's file must be a path inside the recording (relative, without ..), got " +
             e["file"].dump();
    }
    const auto [first_of_file, new_file] = files_.emplace(file.lexically_normal().string(), line_no);
    if (!new_file) {
      return "image file " + first_of_file->first + " recorded twice (first on line " +
             std::to_string(first_of_file->second) + ")";
    }
    if (!e.contains("seq")) return "";
    if (!IsCount(e["seq"])) {
      return "an image event's seq must be a non-negative integer (a frame number), got " + e["seq"].dump();
    }
    const std::string camera = !e.contains("camera")     ? "?"
                               : e["camera"].is_string() ? e["camera"].get<std::string>()
                                                         : e["camera"].dump();
    const auto [first_of_frame, new_frame] = frames_.emplace(std::pair{camera, e["seq"].get<uint64_t>()}, line_no);
    if (!new_frame) {
      return "frame " + camera + "/" + e["seq"].dump() + " recorded twice (first on line " +
             std::to_string(first_of_frame->second) + ")";
    }
    return "";
  }

 private:
  const RecordingHeader& header_;
  std::map<std::string, int> files_;                        // normalised file -> its line
  std::map<std::pair<std::string, uint64_t>, int> frames_;  // (camera, seq) -> its line
};

}  // namespace

Result<Recording> ReadRecording(const std::string& dir) {
  const std::string header_path = (fs::path(dir) / "recording.json").string();
  IDI_ASSIGN_OR_RETURN(const std::string text, ReadFile(header_path));
  const nlohmann::json h = nlohmann::json::parse(text, nullptr, false);
  if (h.is_discarded() || !h.is_object() || !h.contains("format") || h["format"] != "idi-recording") {
    return ParseError(header_path + ": not an idi recording header");
  }
  if (!h.contains("version") || !h["version"].is_number_integer() || h["version"] != kRecordingVersion) {
    return ParseError(header_path + ": recording version " + (h.contains("version") ? h["version"].dump() : "missing") +
                      " (this build reads version " + std::to_string(kRecordingVersion) + ")");
  }
  Recording r;
  r.dir = dir;
  // A field of the wrong type (a version or width written as a string, a null among the params) is a
  // parse error naming the file, not a JSON exception.
  try {
    IDI_RETURN_IF_ERROR(ReadHeaderFields(h, header_path, &r.header));
  } catch (const nlohmann::json::exception& e) {
    return ParseError(header_path + ": " + e.what());
  }
  const std::string events_path = (fs::path(dir) / "events.jsonl").string();
  IDI_ASSIGN_OR_RETURN(const std::string events, ReadFile(events_path));
  EventChecker checker(r.header);
  std::size_t start = 0;
  int line_no = 0;
  while (start < events.size()) {
    const std::size_t nl = events.find('\n', start);
    ++line_no;
    if (nl == std::string::npos) {
      // A last line without its newline: the run was killed while writing it.
      r.truncated = true;
      r.truncated_line = line_no;
      break;
    }
    const std::string line = events.substr(start, nl - start);
    start = nl + 1;
    // A last line of NUL bytes only: the zero-filled tail a filesystem leaves after a power loss (the
    // file's size written, its data not). Torn like a line without its newline; other garbage is an error.
    if (start == events.size() && !line.empty() && line.find_first_not_of('\0') == std::string::npos) {
      r.truncated = true;
      r.truncated_line = line_no;
      break;
    }
    if (line.empty()) continue;
    nlohmann::json e = nlohmann::json::parse(line, nullptr, false);
    if (e.is_discarded() || !e.is_object() || !e.contains("type") || !e.contains("t_ns")) {
      return ParseError(events_path + ":" + std::to_string(line_no) + ": malformed event");
    }
    if (!e["type"].is_string() || !e["t_ns"].is_number_integer()) {
      return ParseError(events_path + ":" + std::to_string(line_no) +
                        ": an event's type must be a string and its t_ns an integer (ns)");
    }
    if (const std::string wrong = checker.Check(e, line_no); !wrong.empty()) {
      return ParseError(events_path + ":" + std::to_string(line_no) + ": " + wrong);
    }
    r.events.push_back(std::move(e));
    r.lines.push_back(line_no);
  }
  return r;
}

Result<std::string> RecordedImagePath(const Recording& recording, const nlohmann::json& e) {
  if (!e.is_object() || !e.contains("type") || e["type"] != "image" || !e.contains("file") || !e["file"].is_string()) {
    return InvalidArgument("not an image event with a file name");
  }
  return (fs::path(recording.dir) / e["file"].get<std::string>()).string();
}

Result<cv::Mat> LoadRecordedImage(const Recording& recording, const nlohmann::json& e) {
  IDI_ASSIGN_OR_RETURN(const std::string path, RecordedImagePath(recording, e));
  return plot::ReadImageFile(path, cv::IMREAD_UNCHANGED);
}

}  // namespace idi
