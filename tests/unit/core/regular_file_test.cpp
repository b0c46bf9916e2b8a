// RegularFile (core/regular_file.hpp): inputs that could block or never end are refused at
// once, and a limit holds while reading.

#include "emcalign/core/regular_file.hpp"

#include <sys/stat.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>

#include <fmt/format.h>
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "emcalign/core/sha256.hpp"

namespace emcalign {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

TEST(RegularFile, RefusesAFifoAtOnceInsteadOfWaitingForAWriter) {
  const fs::path dir = fs::temp_directory_path() / fmt::format("emcalign-regular-{}", ::getpid());
  fs::create_directories(dir);
  const std::string fifo = (dir / "pipe.json").string();
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  const auto started = std::chrono::steady_clock::now();
  auto f = RegularFile::open(fifo);
  ASSERT_FALSE(f);
  EXPECT_THAT(f.error().message, HasSubstr("FIFO"));
  auto digest = sha256OfFile(fifo);
  ASSERT_FALSE(digest);
  EXPECT_LT(std::chrono::steady_clock::now() - started, std::chrono::seconds(2));
  auto directory = RegularFile::open(dir.string());
  ASSERT_FALSE(directory);
  EXPECT_THAT(directory.error().message, HasSubstr("a directory"));
  fs::remove_all(dir);
}

TEST(RegularFile, RefusesDevicesThatNeverEnd) {
  for (const char* device : {"/dev/zero", "/dev/urandom", "/dev/null"}) {
    auto f = RegularFile::open(device);
    ASSERT_FALSE(f) << device;
    EXPECT_THAT(f.error().message, HasSubstr("character device")) << device;
  }
}

TEST(RegularFile, EnforcesItsLimitWhileReading) {
  const fs::path file = fs::temp_directory_path() / fmt::format("emcalign-regular-{}.txt", ::getpid());
  { std::ofstream(file) << std::string(200000, 'x'); }
  auto whole = RegularFile::open(file.string());
  ASSERT_TRUE(whole);
  auto text = whole->readAll(200000);
  ASSERT_TRUE(text) << text.error().message;
  EXPECT_EQ(text->size(), 200000U);
  auto limited = RegularFile::open(file.string());
  ASSERT_TRUE(limited);
  auto refused = limited->readAll(199999);
  ASSERT_FALSE(refused);
  EXPECT_THAT(refused.error().message, HasSubstr("larger than"));
  auto missing = RegularFile::open(file.string() + ".none");
  ASSERT_FALSE(missing);
  EXPECT_THAT(missing.error().message, HasSubstr("no such file"));
  fs::remove(file);
}

}  // namespace
}  // namespace emcalign
