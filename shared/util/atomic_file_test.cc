#include "shared/util/atomic_file.h"

#include <fcntl.h>
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <filesystem>

namespace idi {
namespace {

namespace fs = std::filesystem;

class AtomicFileTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("idi_atomic_" + std::to_string(::getpid()) + "_" +
                                        ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  fs::path dir_;
};

TEST_F(AtomicFileTest, WritesAndReplacesWithoutLeavingTemporaries) {
  const std::string path = (dir_ / "calib.yaml").string();
  ASSERT_TRUE(WriteFileAtomically(path, "first\n").ok());
  EXPECT_EQ(ReadFile(path).value(), "first\n");
  ASSERT_TRUE(WriteFileAtomically(path, "second\n").ok());
  EXPECT_EQ(ReadFile(path).value(), "second\n");
  int files = 0;
  for ([[maybe_unused]] const auto& e : fs::directory_iterator(dir_)) {
    ++files;
  }
  EXPECT_EQ(files, 1);
}

// A new file gets what creating it would give (0666 less the umask; it was always 0644, so a service
// with UMask=0027 wrote world-readable files); a replaced file keeps its mode.
TEST_F(AtomicFileTest, ModeFollowsTheUmaskOrTheReplacedFile) {
  const mode_t old_mask = ::umask(027);
  const std::string path = (dir_ / "new.yaml").string();
  const Status written = WriteFileAtomically(path, "x\n");
  ::umask(old_mask);
  ASSERT_TRUE(written.ok()) << written.ToString();
  EXPECT_EQ(fs::status(path).permissions() & fs::perms::all,
            fs::perms::owner_read | fs::perms::owner_write | fs::perms::group_read);
  fs::permissions(path, fs::perms::owner_read | fs::perms::owner_write);
  ASSERT_TRUE(WriteFileAtomically(path, "y\n").ok());
  EXPECT_EQ(fs::status(path).permissions() & fs::perms::all, fs::perms::owner_read | fs::perms::owner_write);
}

TEST_F(AtomicFileTest, CheckOutputFileBeforeALongRun) {
  EXPECT_TRUE(CheckOutputFile((dir_ / "out.yaml").string(), "--out").ok());
  EXPECT_TRUE(CheckOutputFile("", "--report").ok()) << "an output not asked for";
  const Status folder = CheckOutputFile(dir_.string(), "--out");
  EXPECT_EQ(folder.code(), StatusCode::kInvalidArgument);
  EXPECT_NE(folder.message().find("--out " + dir_.string() + ": is a folder"), std::string::npos) << folder.ToString();
  const Status missing = CheckOutputFile((dir_ / "no" / "out.yaml").string(), "--out");
  EXPECT_EQ(missing.code(), StatusCode::kNotFound);
  EXPECT_NE(missing.message().find("does not exist"), std::string::npos) << missing.ToString();
  // A folder of outputs may not exist yet (it is made later, not by the check).
  EXPECT_TRUE(CheckOutputFolder((dir_ / "plots" / "robot1").string(), "--plots").ok());
  EXPECT_FALSE(fs::exists(dir_ / "plots"));
  EXPECT_TRUE(CheckOutputFolder(dir_.string(), "--plots").ok());
  ASSERT_TRUE(WriteFileAtomically((dir_ / "file").string(), "x").ok());
  EXPECT_EQ(CheckOutputFolder((dir_ / "file" / "plots").string(), "--plots").code(), StatusCode::kInvalidArgument);
}

// A run's output folder is new or empty, so that two runs' results never mix; the entries the command
// keeps there between runs may stay, if they are folders. A link to nothing is refused, not made later.
TEST_F(AtomicFileTest, ANewOutputFolderIsNewOrEmpty) {
  EXPECT_TRUE(CheckNewOutputFolder((dir_ / "new" / "run").string(), "--out").ok());
  fs::create_directories(dir_ / "empty");
  EXPECT_TRUE(CheckNewOutputFolder((dir_ / "empty").string(), "--out").ok());
  fs::create_directories(dir_ / "used" / "calibration");
  const Status held = CheckNewOutputFolder((dir_ / "used").string(), "--out");
  EXPECT_EQ(held.code(), StatusCode::kInvalidArgument);
  EXPECT_NE(held.message().find("it holds 'calibration'"), std::string::npos) << held.message();
  EXPECT_TRUE(CheckNewOutputFolder((dir_ / "used").string(), "--out", {"calibration"}).ok());
  // A file of that name is not the folder the command keeps.
  fs::create_directories(dir_ / "file");
  ASSERT_TRUE(WriteFileAtomically((dir_ / "file" / "calibration").string(), "x\n").ok());
  EXPECT_EQ(CheckNewOutputFolder((dir_ / "file").string(), "--out", {"calibration"}).code(),
            StatusCode::kInvalidArgument);
  fs::create_symlink(dir_ / "nowhere", dir_ / "dangling");
  const Status dangling = CheckNewOutputFolder((dir_ / "dangling").string(), "--out");
  EXPECT_EQ(dangling.code(), StatusCode::kInvalidArgument);
  EXPECT_NE(dangling.message().find("which does not exist"), std::string::npos) << dangling.message();
}

TEST_F(AtomicFileTest, MissingFolderIsAnErrorNamingThePath) {
  const std::string path = (dir_ / "no_such_dir" / "x.yaml").string();
  const Status st = WriteFileAtomically(path, "x");
  EXPECT_EQ(st.code(), StatusCode::kNotFound);
  EXPECT_NE(st.message().find("no_such_dir"), std::string::npos);
}

// A link is followed: the file it names gets the contents and the link stays a link (renaming over it
// replaced the link with a regular file). A relative link is taken from the link's own folder.
TEST_F(AtomicFileTest, ASymbolicLinkIsFollowed) {
  fs::create_directories(dir_ / "real");
  const fs::path target = dir_ / "real" / "calib.yaml";
  ASSERT_TRUE(WriteFileAtomically(target.string(), "old\n").ok());
  const fs::path link = dir_ / "current.yaml";
  fs::create_symlink(fs::path("real") / "calib.yaml", link);
  const Status st = WriteFileAtomically(link.string(), "new\n");
  ASSERT_TRUE(st.ok()) << st.ToString();
  EXPECT_TRUE(fs::is_symlink(link));
  EXPECT_EQ(ReadFile(target.string()).value(), "new\n");
}

// A device node is written in place: /dev/null stays a character device (as root, renaming over it
// replaced the system's /dev/null with a regular file), and /dev/full's "no space" is the error.
TEST_F(AtomicFileTest, ADeviceIsWrittenInPlace) {
  const fs::path null_link = dir_ / "null";
  fs::create_symlink("/dev/null", null_link);
  const Status st = WriteFileAtomically(null_link.string(), "x\n");
  ASSERT_TRUE(st.ok()) << st.ToString();
  ASSERT_TRUE(fs::is_character_file("/dev/null"));
  // (Only then /dev/full: code that renamed over it would, as root, replace the system's.)
  ASSERT_TRUE(fs::is_symlink(null_link));
  if (fs::is_character_file("/dev/full")) {
    const Status full = WriteFileAtomically("/dev/full", "x\n");
    EXPECT_EQ(full.code(), StatusCode::kIoError) << full.ToString();
    EXPECT_NE(full.message().find("/dev/full"), std::string::npos) << full.ToString();
    EXPECT_TRUE(fs::is_character_file("/dev/full"));
  }
  EXPECT_EQ(WriteFileAtomically(dir_.string(), "x").code(), StatusCode::kInvalidArgument) << "a folder";
  // The check before a run agrees: a device is checked itself, not the folder it is in (a user cannot
  // write in /dev, but can write /dev/null), and a link at its file's folder.
  EXPECT_TRUE(CheckOutputFile("/dev/null", "--report").ok());
  EXPECT_TRUE(CheckOutputFile(null_link.string(), "--report").ok());
  fs::create_directories(dir_ / "real");
  fs::create_symlink(dir_ / "real" / "x.yaml", dir_ / "x.yaml");
  EXPECT_TRUE(CheckOutputFile((dir_ / "x.yaml").string(), "--out").ok()) << "a dangling link to a file to be made";
  fs::remove_all(dir_ / "real");
  EXPECT_EQ(CheckOutputFile((dir_ / "x.yaml").string(), "--out").code(), StatusCode::kNotFound)
      << "the link's file's folder is gone";
}

// /dev/stdout and its kind are the descriptor itself: a pipe gets the bytes (its /proc link reads
// "pipe:[N]", which was taken for a file name), and a file opened for appending keeps what it had
// (renaming over it lost the earlier lines).
TEST_F(AtomicFileTest, ADescriptorIsWrittenNotRenamedOver) {
  int p[2];
  ASSERT_EQ(::pipe(p), 0);
  const std::string to_pipe = "/dev/fd/" + std::to_string(p[1]);
  EXPECT_TRUE(CheckOutputFile(to_pipe, "--out").ok());
  ASSERT_TRUE(WriteFileAtomically(to_pipe, "through\n").ok());
  ::close(p[1]);
  char buf[32] = {};
  EXPECT_EQ(::read(p[0], buf, sizeof(buf) - 1), 8);
  EXPECT_STREQ(buf, "through\n");
  ::close(p[0]);
  const std::string log = (dir_ / "log.txt").string();
  ASSERT_TRUE(WriteFileAtomically(log, "before\n").ok());
  struct stat before {};
  ASSERT_EQ(::stat(log.c_str(), &before), 0);
  const int fd = ::open(log.c_str(), O_WRONLY | O_APPEND);
  ASSERT_GE(fd, 0);
  const Status st = WriteFileAtomically("/proc/self/fd/" + std::to_string(fd), "after\n");
  ::close(fd);
  ASSERT_TRUE(st.ok()) << st.ToString();
  EXPECT_EQ(ReadFile(log).value(), "before\nafter\n");
  struct stat after {};
  ASSERT_EQ(::stat(log.c_str(), &after), 0);
  EXPECT_EQ(after.st_ino, before.st_ino) << "the file itself, not a new one renamed over it";
  const int ro = ::open(log.c_str(), O_RDONLY);
  EXPECT_EQ(WriteFileAtomically("/dev/fd/" + std::to_string(ro), "x").code(), StatusCode::kIoError);
  ::close(ro);
}

TEST_F(AtomicFileTest, OutputNamesAreUniqueAndAUniqueStemKeepsItsName) {
  EXPECT_EQ(UniqueOutputNames({"x/a.pgm", "y/a.pgm", "a_2.pgm", "b.png", "z/a.png"}, "_f.png"),
            (std::vector<std::string>{"a_f.png", "a_3_f.png", "a_2_f.png", "b_f.png", "a_4_f.png"}));
  EXPECT_TRUE(UniqueOutputNames({}, "_f.png").empty());
}

TEST_F(AtomicFileTest, AnOutputMayNotBeAnInputOrAnotherOutput) {
  const std::string obs = (dir_ / "obs.csv").string();
  ASSERT_TRUE(WriteFileAtomically(obs, "readings\n").ok());
  const std::string out = (dir_ / "out.yaml").string();
  EXPECT_TRUE(CheckDistinctFiles({{"--observations", obs}}, {{"--out", out}, {"--report", ""}}, "calibrate").ok());
  // The input named another way: relative to the working folder, and through a link.
  const fs::path cwd = fs::current_path();
  fs::current_path(dir_);
  const Status same = CheckDistinctFiles({{"--observations", obs}}, {{"--out", "./obs.csv"}}, "calibrate");
  fs::current_path(cwd);
  EXPECT_EQ(same.code(), StatusCode::kInvalidArgument);
  EXPECT_NE(same.message().find("calibrate: --out ./obs.csv is the same file as the input --observations"),
            std::string::npos)
      << same.ToString();
  fs::create_symlink(obs, dir_ / "link.csv");
  EXPECT_FALSE(CheckDistinctFiles({{"--observations", obs}}, {{"--out", (dir_ / "link.csv").string()}}, "c").ok());
  // Two outputs, neither written yet.
  const Status twice =
      CheckDistinctFiles({}, {{"--out", out}, {"--report", (dir_ / "sub" / ".." / "out.yaml").string()}}, "c");
  EXPECT_EQ(twice.code(), StatusCode::kInvalidArgument);
  EXPECT_NE(twice.message().find("are the same file"), std::string::npos) << twice.ToString();
  EXPECT_FALSE(SameFile(out, obs));
  EXPECT_TRUE(SameFile(out, out));
  // A link to a file not made yet is the file it will write (weakly_canonical alone stops at it).
  fs::create_symlink(dir_ / "later.json", dir_ / "report.json");
  EXPECT_TRUE(SameFile((dir_ / "report.json").string(), (dir_ / "later.json").string()));
  EXPECT_FALSE(CheckDistinctFiles(
                   {}, {{"--out", (dir_ / "later.json").string()}, {"--report", (dir_ / "report.json").string()}}, "c")
                   .ok());
}

// /dev/null for two outputs discards both: a device (or a descriptor) is written in place, neither
// replaces the other. The same through a link; a regular file twice is still refused.
TEST_F(AtomicFileTest, TwoOutputsMayBothGoToADevice) {
  ASSERT_TRUE(fs::is_character_file("/dev/null"));
  fs::create_symlink("/dev/null", dir_ / "null-link");
  EXPECT_TRUE(CheckDistinctFiles({}, {{"--can-log", "/dev/null"}, {"--png", "/dev/null"}}, "sim").ok());
  EXPECT_TRUE(
      CheckDistinctFiles({}, {{"--can-log", "/dev/null"}, {"--report", (dir_ / "null-link").string()}}, "sim").ok());
  // An open descriptor by two names is written twice, in place, even when it is a regular file (stdout
  // redirected to one).
  const int fd = ::open((dir_ / "stream.txt").c_str(), O_WRONLY | O_CREAT | O_CLOEXEC, 0644);
  ASSERT_GE(fd, 0);
  const std::string n = std::to_string(fd);
  EXPECT_TRUE(CheckDistinctFiles({}, {{"--report", "/dev/fd/" + n}, {"--can-log", "/proc/self/fd/" + n}}, "sim").ok());
  ::close(fd);
  const std::string out = (dir_ / "out.json").string();
  ASSERT_TRUE(WriteFileAtomically(out, "{}\n").ok());
  EXPECT_FALSE(CheckDistinctFiles({}, {{"--report", out}, {"--can-log", out}}, "sim").ok());
  // A device as an input and an output is still refused: reading and writing one stream at once.
  EXPECT_FALSE(CheckDistinctFiles({{"--track", "/dev/null"}}, {{"--report", "/dev/null"}}, "sim").ok());
}

TEST_F(AtomicFileTest, ReadMissingFileIsNotFound) {
  const auto r = ReadFile((dir_ / "absent.yaml").string());
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), StatusCode::kNotFound);
  EXPECT_EQ(ReadFile(dir_.string()).status().code(), StatusCode::kInvalidArgument);
}

// A file that may not be read is bad input like a missing one (InvalidArgument: exit 2 in the
// binaries), with the reason (before: IoError, exit 1, no reason).
TEST_F(AtomicFileTest, ReadUnreadableFileIsInvalidArgumentWithTheReason) {
  if (::geteuid() == 0) GTEST_SKIP() << "root reads a file without read permission";
  const std::string path = (dir_ / "secret.yaml").string();
  ASSERT_TRUE(WriteFileAtomically(path, "x: 1\n").ok());
  fs::permissions(path, fs::perms::none);
  const auto r = ReadFile(path);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), StatusCode::kInvalidArgument) << r.status().ToString();
  EXPECT_NE(r.status().message().find(path + ": cannot open for reading: Permission denied"), std::string::npos)
      << r.status().message();
}

}  // namespace
}  // namespace idi
