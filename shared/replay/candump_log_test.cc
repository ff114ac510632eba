#include "shared/replay/candump_log.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <string>

#include "shared/util/atomic_file.h"

namespace idi::replay {
namespace {

hal::CanFrame MakeFrame(int64_t t_ns, uint32_t id, std::initializer_list<uint8_t> bytes) {
  hal::CanFrame f;
  f.timestamp_ns = t_ns;
  f.id = id;
  f.dlc = static_cast<uint8_t>(bytes.size());
  std::size_t i = 0;
  for (uint8_t b : bytes) f.data[i++] = b;
  return f;
}

// A line as `candump -l` writes it: "(" 10 digits "." 6 digits ") " IFACE " " 3 hex "#" data bytes.
bool LooksLikeCandumpLine(const std::string& line, const std::string& iface, int min_bytes, int max_bytes) {
  auto hex = [](char c) { return (c >= '0' && c <= '9') || (c >= 'A' && c <= 'F'); };
  auto digit = [](char c) { return c >= '0' && c <= '9'; };
  if (line.size() < 19 || line[0] != '(' || line[11] != '.' || line[18] != ')') return false;
  for (int i = 1; i <= 17; ++i) {
    if (i != 11 && !digit(line[static_cast<std::size_t>(i)])) return false;
  }
  const std::string rest = line.substr(19);
  const std::string head = " " + iface + " ";
  if (rest.compare(0, head.size(), head) != 0) return false;
  const std::string frame = rest.substr(head.size());
  if (frame.size() < 4 || frame[3] != '#' || !hex(frame[0]) || !hex(frame[1]) || !hex(frame[2])) return false;
  const std::string data = frame.substr(4);
  if (data.size() % 2 != 0) return false;
  const int bytes = static_cast<int>(data.size() / 2);
  if (bytes < min_bytes || bytes > max_bytes) return false;
  for (char c : data) {
    if (!hex(c)) return false;
  }
  return true;
}

std::string CandumpTempPath(const std::string& name) {
  return (std::filesystem::path(::testing::TempDir()) / ("candump_" + name + "_" + std::to_string(::getpid()) + ".log")).string();
}

TEST(CandumpFormat, StandardFrameAsCandumpWritesIt) {
  const hal::CanFrame f = MakeFrame(1234567890'123456'000LL, 0x413, {0x00, 0x11, 0x22, 0x33, 0x44, 0x55, 0x66, 0x77});
  EXPECT_EQ(FormatCandumpLine(f, "can0"), "(1234567890.123456) can0 413#0011223344556677");
}

TEST(CandumpFormat, SmallTimestampsArePaddedToTenDigitsAndMicrosecondsTruncate) {
  const hal::CanFrame f = MakeFrame(10'000'999, 0x7, {0xAB});
  EXPECT_EQ(FormatCandumpLine(f, "vcan0"), "(0000000000.010000) vcan0 007#AB");
}

TEST(CandumpFormat, ExtendedErrorRemoteAndEmptyFrames) {
  hal::CanFrame ext = MakeFrame(0, 0x1ABCDEF, {0x01});
  ext.extended = true;
  EXPECT_EQ(FormatCanFrameText(ext), "01ABCDEF#01");
  hal::CanFrame err = MakeFrame(0, 0x40, {0, 0, 0, 0, 0, 0, 0, 0});
  err.error = true;
  EXPECT_EQ(FormatCanFrameText(err), "20000040#0000000000000000");
  hal::CanFrame rtr = MakeFrame(0, 0x123, {});
  rtr.rtr = true;
  EXPECT_EQ(FormatCanFrameText(rtr), "123#R");
  rtr.dlc = 3;
  EXPECT_EQ(FormatCanFrameText(rtr), "123#R3");
  EXPECT_EQ(FormatCanFrameText(MakeFrame(0, 0x400, {})), "400#");
}

TEST(CandumpFormat, DirectionMarks) {
  const hal::CanFrame f = MakeFrame(1'500'000'000, 0x402, {1, 2});
  EXPECT_EQ(FormatCandumpLine(f, "can0", CanDirection::kReceived), "(0000000001.500000) can0 402#0102 R");
  EXPECT_EQ(FormatCandumpLine(f, "can0", CanDirection::kTransmitted), "(0000000001.500000) can0 402#0102 T");
}

TEST(CandumpParse, RoundTripsEveryKindOfFrame) {
  std::vector<hal::CanFrame> frames = {MakeFrame(5, 0x413, {0xFB, 0x68, 0x04, 0x00, 0x00, 0x32, 0x00, 0x0F}),
                                       MakeFrame(1'000'001'000, 0x0, {}), MakeFrame(2'000'000'000, 0x7FF, {0xFF})};
  hal::CanFrame ext = MakeFrame(3'000'000'000, 0x1FFFFFFF, {1, 2, 3});
  ext.extended = true;
  frames.push_back(ext);
  hal::CanFrame err = MakeFrame(4'000'000'000, 0x104, {0, 0x40, 0, 0, 0, 0, 0, 0});
  err.error = true;
  frames.push_back(err);
  hal::CanFrame rtr = MakeFrame(5'000'000'000, 0x555, {});
  rtr.rtr = true;
  rtr.dlc = 8;
  frames.push_back(rtr);
  for (const hal::CanFrame& f : frames) {
    const std::string line = FormatCandumpLine(f, "can1");
    Result<CandumpRecord> r = ParseCandumpLine(line);
    ASSERT_TRUE(r.ok()) << line << ": " << r.status().ToString();
    EXPECT_EQ(r->interface, "can1");
    EXPECT_EQ(r->frame.id, f.id) << line;
    EXPECT_EQ(r->frame.extended, f.extended) << line;
    EXPECT_EQ(r->frame.error, f.error) << line;
    EXPECT_EQ(r->frame.rtr, f.rtr) << line;
    EXPECT_EQ(r->frame.dlc, f.dlc) << line;
    if (!f.rtr) {
      EXPECT_EQ(r->frame.data, f.data) << line;
    }
    EXPECT_EQ(r->frame.timestamp_ns, f.timestamp_ns / 1000 * 1000) << line;
  }
}

TEST(CandumpParse, AcceptsDotSeparatorsLowerCaseAndDirection) {
  Result<CandumpRecord> r = ParseCandumpLine("(1700000000.000042) can0 413#fb.68.04.00 T");
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  EXPECT_EQ(r->frame.dlc, 4);
  EXPECT_EQ(r->frame.data[0], 0xFB);
  EXPECT_EQ(r->frame.data[3], 0x00);
  EXPECT_EQ(r->direction, CanDirection::kTransmitted);
  EXPECT_EQ(r->frame.timestamp_ns, 1700000000'000042'000LL);
}

TEST(CandumpParse, RejectsMalformedLinesWithAReason) {
  const std::vector<std::pair<std::string, std::string>> bad = {
      {"(1.000000) can0 4130011", "no '#'"},
      {"(1.000000) can0 4130#00", "3 (standard) or 8"},
      {"(1.000000) can0 800#00", "exceeds 0x7FF"},
      {"(1.000000) can0 413#001", "odd number"},
      {"(1.000000) can0 413#001122334455667788", "more than 8"},
      {"(1.000000) can0 413##1001122", "CAN FD"},
      {"(1.000000) can0 413#0G", "not a hex byte"},
      {"(1.0) can0 413#00", "six digits"},
      {"1.000000 can0 413#00", "timestamp"},
      {"(1.000000) can0", "expected"},
      {"(1.000000) can0 413#00 X", "trailing"},
      {"(1.000000) can0 413#R9", "length digit"},
      {"(1.000000) averyveryverylongname 413#00", "15 characters"},
  };
  for (const auto& [line, reason] : bad) {
    Result<CandumpRecord> r = ParseCandumpLine(line, "test.log:7");
    ASSERT_FALSE(r.ok()) << line;
    EXPECT_EQ(r.status().code(), StatusCode::kParseError) << line;
    EXPECT_NE(r.status().message().find(reason), std::string::npos) << line << " -> " << r.status().message();
    EXPECT_NE(r.status().message().find("test.log:7"), std::string::npos) << r.status().message();
  }
}

TEST(CandumpParse, TextSkipsCommentsAndNamesTheBadLine) {
  const std::string text =
      "# recorded by idi-rmp\n"
      "\n"
      "(0000000000.010000) can0 400#0001000000000000\n"
      "(0000000000.010250) can0 401#0000000000000000\r\n";
  Result<std::vector<CandumpRecord>> ok = ParseCandumpText(text, "a.log");
  ASSERT_TRUE(ok.ok()) << ok.status().ToString();
  ASSERT_EQ(ok->size(), 2u);
  EXPECT_EQ((*ok)[0].line, 3);
  EXPECT_EQ((*ok)[1].frame.id, 0x401u);
  EXPECT_EQ((*ok)[1].frame.timestamp_ns, 10'250'000);

  Result<std::vector<CandumpRecord>> bad = ParseCandumpText(text + "(0000000000.020000) can0 402#0\n", "a.log");
  ASSERT_FALSE(bad.ok());
  EXPECT_NE(bad.status().message().find("a.log:5"), std::string::npos) << bad.status().message();
  // The same bad line as the file's last, without its newline: a writer killed mid-line; the rest is kept.
  std::string dropped;
  int dropped_line = -1;
  Result<std::vector<CandumpRecord>> torn =
      ParseCandumpText(text + "(0000000000.020000) can0 402#00112", "a.log", &dropped, &dropped_line);
  ASSERT_TRUE(torn.ok()) << torn.status().ToString();
  EXPECT_EQ(torn->size(), 2u);
  EXPECT_EQ(dropped, "(0000000000.020000) can0 402#00112");
  EXPECT_EQ(dropped_line, 5);
  // Cut after an even number of data digits it would parse, as a shorter frame: dropped all the same.
  Result<std::vector<CandumpRecord>> cut =
      ParseCandumpText(text + "(0000000000.020000) can0 402#0011", "a.log", &dropped);
  ASSERT_TRUE(cut.ok()) << cut.status().ToString();
  EXPECT_EQ(cut->size(), 2u);
  EXPECT_EQ(dropped, "(0000000000.020000) can0 402#0011");
  // A log whose every line ends: nothing dropped.
  ASSERT_TRUE(ParseCandumpText(text, "a.log", &dropped, &dropped_line).ok());
  EXPECT_TRUE(dropped.empty());
  EXPECT_EQ(dropped_line, 0);
}

TEST(CandumpFile, MissingFileIsNotFound) {
  Result<std::vector<CandumpRecord>> r = ReadCandumpFile("/nonexistent/dir/x.log");
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), StatusCode::kNotFound);
}

TEST(CandumpWriterTest, WritesCanplayerLinesThatParseBack) {
  const std::string path = CandumpTempPath("writer");
  CandumpWriterOptions options;
  options.interface = "can0";
  options.timestamp_offset_ns = 1'700'000'000'000'000'000LL;
  auto writer = CandumpWriter::Open(path, options);
  ASSERT_TRUE(writer.ok()) << writer.status().ToString();
  std::vector<hal::CanFrame> frames;
  for (int i = 0; i < 50; ++i) {
    frames.push_back(MakeFrame(i * 20'000'000LL + 1234, 0x400 + static_cast<uint32_t>(i % 8),
                               {static_cast<uint8_t>(i), 0x80, 0xFF, 0, 1, 2, 3, static_cast<uint8_t>(255 - i)}));
    ASSERT_TRUE((*writer)->Write(frames.back()).ok());
  }
  ASSERT_TRUE((*writer)->Close().ok());
  EXPECT_EQ((*writer)->lines_written(), 50u);
  EXPECT_FALSE((*writer)->Write(frames[0]).ok()) << "writing after Close must fail";

  Result<std::string> text = ReadFile(path);
  ASSERT_TRUE(text.ok());
  // The line checker itself: it must refuse near misses.
  EXPECT_TRUE(LooksLikeCandumpLine("(0000000001.000000) can0 413#00FF", "can0", 0, 8));
  EXPECT_FALSE(LooksLikeCandumpLine("(1.000000) can0 413#00", "can0", 0, 8));
  EXPECT_FALSE(LooksLikeCandumpLine("(0000000001.000000) can0 413#0", "can0", 0, 8));
  EXPECT_FALSE(LooksLikeCandumpLine("(0000000001.000000) can0 413#0g", "can0", 0, 8));
  EXPECT_FALSE(LooksLikeCandumpLine("(0000000001.000000) can1 413#00", "can0", 0, 8));
  std::size_t pos = 0, lines = 0;
  while (pos < text->size()) {
    const std::size_t end = text->find('\n', pos);
    ASSERT_NE(end, std::string::npos) << "every line ends with a newline";
    const std::string line = text->substr(pos, end - pos);
    EXPECT_TRUE(LooksLikeCandumpLine(line, "can0", 0, 8)) << line;
    pos = end + 1;
    ++lines;
  }
  EXPECT_EQ(lines, 50u);

  Result<std::vector<CandumpRecord>> back = ReadCandumpFile(path);
  ASSERT_TRUE(back.ok()) << back.status().ToString();
  ASSERT_EQ(back->size(), frames.size());
  for (std::size_t i = 0; i < frames.size(); ++i) {
    EXPECT_EQ((*back)[i].frame.id, frames[i].id);
    EXPECT_EQ((*back)[i].frame.data, frames[i].data);
    EXPECT_EQ((*back)[i].frame.timestamp_ns, (frames[i].timestamp_ns + options.timestamp_offset_ns) / 1000 * 1000);
  }
  std::filesystem::remove(path);
}

TEST(CandumpWriterTest, RejectsBadOptionsNegativeTimesAndUnwritablePaths) {
  CandumpWriterOptions options;
  options.interface = "can 0";
  EXPECT_EQ(CandumpWriter::Open(CandumpTempPath("bad"), options).status().code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(CandumpWriter::Open("/nonexistent/dir/x.log").status().code(), StatusCode::kIoError);
  const std::string path = CandumpTempPath("neg");
  auto writer = CandumpWriter::Open(path);
  ASSERT_TRUE(writer.ok());
  EXPECT_EQ((*writer)->Write(MakeFrame(-5, 0x400, {})).code(), StatusCode::kInvalidArgument);
  std::filesystem::remove(path);
}

}  // namespace
}  // namespace idi::replay
