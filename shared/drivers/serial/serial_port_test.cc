#include "shared/drivers/serial/serial_port.h"

#include <gtest/gtest.h>
#include <sys/socket.h>
#include <unistd.h>

#include "shared/drivers/serial/pty.h"

namespace idi::drivers {
namespace {

using std::chrono::milliseconds;

// A driver-side port on the slave and the emulator side on the master of one pty.
struct SerialTestPair {
  PtyPair pty;
  std::unique_ptr<SerialPort> device;  // master side, what a device would see
  std::unique_ptr<SerialPort> host;    // slave side, opened by path like /dev/ttyUSB0

  static SerialTestPair Make(SerialOptions options = {}) {
    auto pty = PtyPair::Open();
    IDI_CHECK(pty.ok(), pty.status().ToString());
    SerialTestPair pair{std::move(pty).value(), nullptr, nullptr};
    auto host = SerialPort::Open(pair.pty.slave_path(), options);
    IDI_CHECK(host.ok(), host.status().ToString());
    pair.host = std::move(host).value();
    pair.device = SerialPort::FromFd(pair.pty.ReleaseMaster(), "device", options);
    return pair;
  }
};

TEST(SerialPortTest, ReadsLinesEndedByCrOrLfAndSkipsBlankLines) {
  auto p = SerialTestPair::Make();
  ASSERT_TRUE(p.device->Write("hello\r\nworld\n\r\n* 42\r", milliseconds(100)).ok());
  EXPECT_EQ(p.host->ReadLine(milliseconds(200)).value(), "hello");
  EXPECT_EQ(p.host->ReadLine(milliseconds(200)).value(), "world");
  EXPECT_EQ(p.host->ReadLine(milliseconds(200)).value(), "* 42");
  const auto none = p.host->ReadLine(milliseconds(20));
  EXPECT_EQ(none.status().code(), StatusCode::kTimeout);
  EXPECT_NE(none.status().message().find(p.pty.slave_path()), std::string::npos) << none.status().message();
}

TEST(SerialPortTest, PartialLineSurvivesATimeout) {
  auto p = SerialTestPair::Make();
  ASSERT_TRUE(p.device->Write("* 12", milliseconds(100)).ok());
  EXPECT_EQ(p.host->ReadLine(milliseconds(30)).status().code(), StatusCode::kTimeout);
  ASSERT_TRUE(p.device->Write("34\r\n", milliseconds(100)).ok());
  EXPECT_EQ(p.host->ReadLine(milliseconds(200)).value(), "* 1234");
}

TEST(SerialPortTest, ReadUntilStopsAtThePrompt) {
  auto p = SerialTestPair::Make();
  ASSERT_TRUE(p.device->Write("GC\r\n=> 1FGET P\r\n1234\r\n=> ", milliseconds(100)).ok());
  EXPECT_EQ(p.host->ReadUntil("=> ", milliseconds(200)).value(), "GC\r\n");
  EXPECT_EQ(p.host->ReadUntil("=> ", milliseconds(200)).value(), "1FGET P\r\n1234\r\n");
  EXPECT_EQ(p.host->ReadUntil("=> ", milliseconds(20)).status().code(), StatusCode::kTimeout);
}

TEST(SerialPortTest, EndlessGarbageIsDroppedWithAClearErrorAndTheNextLineIsRead) {
  SerialOptions options;
  options.max_line_bytes = 64;
  auto p = SerialTestPair::Make(options);
  ASSERT_TRUE(p.device->Write(std::string(200, '\x7f'), milliseconds(100)).ok());
  const auto garbage = p.host->ReadLine(milliseconds(200));
  ASSERT_EQ(garbage.status().code(), StatusCode::kDeviceError);
  EXPECT_NE(garbage.status().message().find("without a line end"), std::string::npos);
  p.host->DrainUntilQuiet(milliseconds(20), milliseconds(200));
  ASSERT_TRUE(p.device->Write("*\r\n", milliseconds(100)).ok());
  EXPECT_EQ(p.host->ReadLine(milliseconds(200)).value(), "*");
}

// A line longer than the limit is dropped whole: one whose end arrived with it, and one that overflowed
// before its end, whose tail was returned by the next call as if it were a reply.
TEST(SerialPortTest, AnOverlongLineIsDroppedWholeAndItsTailIsNeverALine) {
  SerialOptions options;
  options.max_line_bytes = 64;
  auto p = SerialTestPair::Make(options);
  ASSERT_TRUE(p.device->Write(std::string(200, 'x') + "\r*\r", milliseconds(100)).ok());
  const auto whole = p.host->ReadLine(milliseconds(200));
  ASSERT_EQ(whole.status().code(), StatusCode::kDeviceError);
  EXPECT_NE(whole.status().message().find("a line of 200 bytes"), std::string::npos) << whole.status().message();
  EXPECT_EQ(p.host->ReadLine(milliseconds(200)).value(), "*");

  ASSERT_TRUE(p.device->Write(std::string(200, 'x'), milliseconds(100)).ok());
  const auto overflow = p.host->ReadLine(milliseconds(200));
  ASSERT_EQ(overflow.status().code(), StatusCode::kDeviceError);
  ASSERT_TRUE(p.device->Write("yyy\r* 1\r", milliseconds(100)).ok());
  const auto next = p.host->ReadLine(milliseconds(200));
  ASSERT_TRUE(next.ok()) << next.status().ToString();
  EXPECT_EQ(*next, "* 1");  // not "yyy", the overlong line's tail
  // An overflow followed by quiet: the overlong line has ended, and the next reply is read whole.
  ASSERT_TRUE(p.device->Write(std::string(200, 'x'), milliseconds(100)).ok());
  EXPECT_EQ(p.host->ReadLine(milliseconds(200)).status().code(), StatusCode::kDeviceError);
  EXPECT_EQ(p.host->ReadLine(milliseconds(30)).status().code(), StatusCode::kTimeout);
  ASSERT_TRUE(p.device->Write("* 2\r", milliseconds(100)).ok());
  EXPECT_EQ(p.host->ReadLine(milliseconds(200)).value(), "* 2");
}

TEST(SerialPortTest, AnOverlongBlockBeforeAPromptIsDroppedWhole) {
  SerialOptions options;
  options.max_line_bytes = 64;
  auto p = SerialTestPair::Make(options);
  ASSERT_TRUE(p.device->Write(std::string(100, 'G') + "=> ok=> ", milliseconds(100)).ok());
  EXPECT_EQ(p.host->ReadUntil("=> ", milliseconds(200)).status().code(), StatusCode::kDeviceError);
  EXPECT_EQ(p.host->ReadUntil("=> ", milliseconds(200)).value(), "ok");
  ASSERT_TRUE(p.device->Write(std::string(200, 'G'), milliseconds(100)).ok());
  EXPECT_EQ(p.host->ReadUntil("=> ", milliseconds(200)).status().code(), StatusCode::kDeviceError);
  // The rest of the block, its delimiter split across writes, is dropped with it.
  ASSERT_TRUE(p.device->Write("GGG=", milliseconds(100)).ok());
  ASSERT_TRUE(p.device->Write("> 1234\r\n=> ", milliseconds(100)).ok());
  EXPECT_EQ(p.host->ReadUntil("=> ", milliseconds(200)).value(), "1234\r\n");
  // An overflow followed by quiet: that block has ended, and the next one is read whole.
  ASSERT_TRUE(p.device->Write(std::string(200, 'G'), milliseconds(100)).ok());
  EXPECT_EQ(p.host->ReadUntil("=> ", milliseconds(200)).status().code(), StatusCode::kDeviceError);
  EXPECT_EQ(p.host->ReadUntil("=> ", milliseconds(30)).status().code(), StatusCode::kTimeout);
  ASSERT_TRUE(p.device->Write("ok=> ", milliseconds(100)).ok());
  EXPECT_EQ(p.host->ReadUntil("=> ", milliseconds(200)).value(), "ok");
}

// On a socket (the VAL3 link) there is no tcflush: a late reply the kernel holds is dropped too.
TEST(SerialPortTest, DiscardInputDropsWhatASocketHolds) {
  int fds[2];
  ASSERT_EQ(::socketpair(AF_UNIX, SOCK_STREAM, 0, fds), 0);
  auto host = SerialPort::FromFd(fds[0], "socket", {});
  ASSERT_EQ(::write(fds[1], "late\r", 5), 5);
  ::usleep(20000);
  EXPECT_EQ(host->DiscardInput(), 5u);
  ASSERT_EQ(::write(fds[1], "fresh\r", 6), 6);
  EXPECT_EQ(host->ReadLine(milliseconds(200)).value(), "fresh");
  ::close(fds[1]);
}

TEST(SerialPortTest, WritesReachTheOtherEndUnchanged) {
  auto p = SerialTestPair::Make();
  // Raw mode: no CR/LF translation, no echo, bytes above 0x7f pass.
  const std::string bytes = std::string("PP1000 \r\n\x03\xff", 10);
  ASSERT_TRUE(p.host->Write(bytes, milliseconds(100)).ok());
  std::string got;
  while (got.size() < bytes.size()) {
    auto chunk = p.device->ReadSome(milliseconds(200));
    ASSERT_TRUE(chunk.ok()) << chunk.status().ToString();
    got += chunk.value();
  }
  EXPECT_EQ(got, bytes);
}

TEST(SerialPortTest, DrainUntilQuietReturnsPowerUpChatter) {
  auto p = SerialTestPair::Make();
  ASSERT_TRUE(p.device->Write("Initializing...\r\nindependent (default) speed control mode\r\n", milliseconds(100)).ok());
  const std::string dropped = p.host->DrainUntilQuiet(milliseconds(30), milliseconds(500));
  EXPECT_NE(dropped.find("speed control mode"), std::string::npos);
  EXPECT_EQ(p.host->buffered(), 0u);
  EXPECT_EQ(p.host->ReadLine(milliseconds(20)).status().code(), StatusCode::kTimeout);
}

TEST(SerialPortTest, OpenReportsMissingDevicesAndBadSettings) {
  const auto missing = SerialPort::Open("/dev/does-not-exist-idi", {});
  EXPECT_EQ(missing.status().code(), StatusCode::kNotFound);
  EXPECT_NE(missing.status().message().find("/dev/does-not-exist-idi"), std::string::npos);
  const auto not_tty = SerialPort::Open("/dev/null", {});
  EXPECT_EQ(not_tty.status().code(), StatusCode::kInvalidArgument);
  SerialOptions bad;
  bad.baud = 12345;
  const auto bad_baud = SerialPort::Open("/dev/null", bad);
  EXPECT_EQ(bad_baud.status().code(), StatusCode::kInvalidArgument);
  EXPECT_NE(bad_baud.status().message().find("12345"), std::string::npos);
  EXPECT_TRUE(BaudToTermiosSpeed(38400).ok());
}

TEST(SerialPortTest, HangUpOfTheOtherEndIsAnIoError) {
  auto pty = PtyPair::Open();
  ASSERT_TRUE(pty.ok());
  auto host = SerialPort::Open(pty->slave_path(), {});
  ASSERT_TRUE(host.ok()) << host.status().ToString();
  // Closing the master (and the pair's own slave descriptor) is an unplugged device.
  { PtyPair gone = std::move(pty).value(); }
  const auto read = (*host)->ReadLine(milliseconds(200));
  EXPECT_EQ(read.status().code(), StatusCode::kIoError) << read.status().ToString();
}

}  // namespace
}  // namespace idi::drivers
