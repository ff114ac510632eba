#include "shared/replay/drive_log.h"

#include <cstdio>
#include <filesystem>
#include <map>

namespace idi::replay {

namespace fs = std::filesystem;

namespace {

// A CAN log time as candump writes it: seconds with six decimals.
std::string LogTime(int64_t t_ns) {
  char buf[32];
  std::snprintf(buf,
                sizeof(buf),
                "%lld.%06lld",
                static_cast<long long>(t_ns / 1'000'000'000),
                static_cast<long long>(t_ns % 1'000'000'000 / 1000));
  return buf;
}

}  // namespace

Result<std::unique_ptr<DriveLogWriter>> DriveLogWriter::Create(const std::string& dir, const RecordingHeader& header) {
  RecordingHeader h = header;
  h.kind = kDriveLogKind;
  IDI_ASSIGN_OR_RETURN(RecordingWriter rec, RecordingWriter::Create(dir, h));
  CandumpWriterOptions can_options;
  can_options.mark_direction = true;
  IDI_ASSIGN_OR_RETURN(std::unique_ptr<CandumpWriter> can,
                       CandumpWriter::Open((fs::path(dir) / kDriveLogCanFile).string(), can_options));
  return std::unique_ptr<DriveLogWriter>(new DriveLogWriter(std::move(rec), std::move(can)));
}

DriveLogWriter::~DriveLogWriter() = default;

Status DriveLogWriter::AddFrame(const hal::Image& image) {
  return recording_.AddImage(image.timestamp_ns, image.camera, image.sequence, image.pixels);
}

Status DriveLogWriter::AddDelivered(int64_t t_ns, const std::string& camera, uint64_t seq) {
  return recording_.Add(t_ns, {{"type", "delivered"}, {"camera", camera}, {"seq", seq}});
}

Status DriveLogWriter::AddTick(const DriveTickRecord& t) {
  // The CAN frames up to this tick reach the file with it (a killed run loses at most one tick of them).
  IDI_RETURN_IF_ERROR(can_->Flush());
  return recording_.Add(t.t_ns,
                        {{"type", "tick"},
                         {"left_seq", t.left_seq},
                         {"right_seq", t.right_seq},
                         {"speed_mps", t.speed_mps},
                         {"yaw_rate_rps", t.yaw_rate_rps},
                         {"decision", t.decision},
                         {"state", t.state}});
}

Status DriveLogWriter::Finish(const nlohmann::json& final_meta) {
  IDI_RETURN_IF_ERROR(can_->Close());
  return recording_.Finish(final_meta);
}

Result<DriveLog> ReadDriveLog(const std::string& dir) {
  if (!fs::is_directory(dir)) return NotFound(dir + ": no such log directory");
  DriveLog log;
  IDI_ASSIGN_OR_RETURN(log.recording, ReadRecording(dir));
  if (log.recording.header.kind != kDriveLogKind) {
    return ParseError(dir + "/recording.json: kind is '" + log.recording.header.kind + "', expected '" + kDriveLogKind +
                      "'");
  }
  const std::string events = dir + "/events.jsonl";
  std::map<std::pair<std::string, uint64_t>, std::size_t> frame_index;
  for (std::size_t i = 0; i < log.recording.events.size(); ++i) {
    const nlohmann::json& e = log.recording.events[i];
    const std::string where = events + ":" + std::to_string(log.recording.lines[i]);
    std::string type;
    // A sequence number must be a non-negative integer (-1 read as uint64 was 2^64 - 1).
    auto seq_of = [&](const nlohmann::json& v) -> Result<uint64_t> {
      if (!v.is_number_unsigned()) return ParseError(where + ": seq must be a non-negative integer, got " + v.dump());
      return v.get<uint64_t>();
    };
    try {
      type = e.at("type").get<std::string>();
      if (type == "image") {
        DriveFrameRecord f;
        f.camera = e.at("camera").get<std::string>();
        IDI_ASSIGN_OR_RETURN(f.seq, seq_of(e.at("seq")));
        f.exposure_ns = e.at("t_ns").get<int64_t>();
        if (!e.contains("file") || !e["file"].is_string())
          return ParseError(where + ": an image event needs its file name");
        f.event = i;
        // A frame recorded twice (a hand-merged or damaged log) would leave its first copy undelivered.
        const auto [at, inserted] = frame_index.emplace(std::make_pair(f.camera, f.seq), log.frames.size());
        if (!inserted) {
          return ParseError(where + ": frame " + f.camera + "/" + std::to_string(f.seq) +
                            " recorded twice (first on line " +
                            std::to_string(log.recording.lines[log.frames[at->second].event]) + ")");
        }
        log.frames.push_back(f);
      } else if (type == "delivered") {
        const std::string camera = e.at("camera").get<std::string>();
        IDI_ASSIGN_OR_RETURN(const uint64_t seq, seq_of(e.at("seq")));
        const auto it = frame_index.find({camera, seq});
        if (it == frame_index.end()) return ParseError(where + ": delivery of a frame that was never recorded");
        if (log.frames[it->second].delivered_ns >= 0) {
          return ParseError(where + ": frame " + camera + "/" + std::to_string(seq) + " delivered twice");
        }
        log.frames[it->second].delivered_ns = e.at("t_ns").get<int64_t>();
      } else if (type == "tick") {
        DriveTickRecord t;
        t.t_ns = e.at("t_ns").get<int64_t>();
        t.left_seq = e.at("left_seq").get<int64_t>();
        t.right_seq = e.at("right_seq").get<int64_t>();
        t.speed_mps = e.at("speed_mps").get<double>();
        t.yaw_rate_rps = e.at("yaw_rate_rps").get<double>();
        t.decision = e.at("decision").get<std::string>();
        t.state = e.at("state").get<std::string>();
        t.line = log.recording.lines[i];
        // The replay runs the ticks on one clock: a tick at or before the previous one cannot be rerun.
        if (!log.ticks.empty() && t.t_ns <= log.ticks.back().t_ns) {
          return ParseError(where + ": tick at t_ns " + std::to_string(t.t_ns) + " is not after the tick before it (" +
                            std::to_string(log.ticks.back().t_ns) + " on line " +
                            std::to_string(log.ticks.back().line) + "): ticks must be in time order");
        }
        log.ticks.push_back(std::move(t));
      }
    } catch (const nlohmann::json::exception& ex) {
      return ParseError(where + " (" + type + "): " + ex.what());
    }
  }
  const std::string can_path = (fs::path(dir) / kDriveLogCanFile).string();
  if (!fs::exists(can_path)) return NotFound(can_path + ": the drive log has no CAN log");
  IDI_ASSIGN_OR_RETURN(log.can, ReadCandumpFile(can_path, &log.can_torn_last_line, &log.can_torn_line));
  // The driver writes its frames as they come, on one clock: a time that goes backwards is a damaged or
  // hand-edited log, which the replay would feed in a different order than the recorded run saw it.
  for (std::size_t k = 1; k < log.can.size(); ++k) {
    const CandumpRecord &before = log.can[k - 1], &r = log.can[k];
    if (r.frame.timestamp_ns < before.frame.timestamp_ns) {
      return ParseError(can_path + ":" + std::to_string(r.line) + ": the time goes backwards (" +
                        LogTime(r.frame.timestamp_ns) + " s after " + LogTime(before.frame.timestamp_ns) +
                        " s on line " + std::to_string(before.line) + "); a drive log's CAN frames are in time order");
    }
  }
  return log;
}

Result<hal::Image> LoadDriveFrame(const DriveLog& log, const DriveFrameRecord& frame) {
  if (frame.event >= log.recording.events.size()) return InvalidArgument("drive log: frame event index out of range");
  IDI_ASSIGN_OR_RETURN(cv::Mat pixels, LoadRecordedImage(log.recording, log.recording.events[frame.event]));
  hal::Image img;
  img.timestamp_ns = frame.exposure_ns;
  img.sequence = frame.seq;
  img.camera = frame.camera;
  img.pixels = std::move(pixels);
  return img;
}

}  // namespace idi::replay
