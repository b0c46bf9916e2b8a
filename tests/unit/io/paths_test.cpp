// io::isWithin: a path inside a directory, through links, with a trailing separator, and not
// by a common prefix of names.

#include "emcalign/io/paths.hpp"

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <string>

namespace {

namespace fs = std::filesystem;
using emcalign::io::isWithin;

TEST(Paths, WithinIsByDirectoryNotByTextAndFollowsLinks) {
  const fs::path dir = fs::temp_directory_path() / ("emcalign_paths_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir / "out" / "sub");
  fs::create_directories(dir / "outside");
  fs::create_directory_symlink(dir / "out", dir / "link");
  const auto p = [&](const char* name) { return (dir / name).string(); };
  EXPECT_TRUE(isWithin(p("out"), p("out")));
  EXPECT_TRUE(isWithin(p("out/sub"), p("out")));
  EXPECT_TRUE(isWithin(p("out/sub/new.json"), p("out/")));  // not yet there, trailing separator
  EXPECT_TRUE(isWithin(p("link/sub"), p("out")));           // through a link
  EXPECT_TRUE(isWithin(p("out/../out/sub"), p("out")));
  EXPECT_FALSE(isWithin(p("outside"), p("out")));  // a common prefix of names is not inside
  EXPECT_FALSE(isWithin(p("out"), p("out/sub")));
  EXPECT_FALSE(isWithin(p("out/../outside/x"), p("out")));
  fs::remove_all(dir);
}

}  // namespace
