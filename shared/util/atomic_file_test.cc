#include "shared/util/atomic_file.h"

#include <gtest/gtest.h>

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

TEST_F(AtomicFileTest, MissingFolderIsAnErrorNamingThePath) {
  const std::string path = (dir_ / "no_such_dir" / "x.yaml").string();
  const Status st = WriteFileAtomically(path, "x");
  EXPECT_EQ(st.code(), StatusCode::kNotFound);
  EXPECT_NE(st.message().find("no_such_dir"), std::string::npos);
}

TEST_F(AtomicFileTest, ReadMissingFileIsNotFound) {
  const auto r = ReadFile((dir_ / "absent.yaml").string());
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), StatusCode::kNotFound);
  EXPECT_EQ(ReadFile(dir_.string()).status().code(), StatusCode::kInvalidArgument);
}

}  // namespace
}  // namespace idi
