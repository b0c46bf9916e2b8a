// The output rules of io/output_file.hpp: what is written directly, through a temporary,
// or refused, and that temporaries never outlive their writer.

#include "emcalign/io/output_file.hpp"

#include <fcntl.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <thread>

#include <fmt/format.h>
#include <gmock/gmock.h>
#include <gtest/gtest.h>

namespace emcalign::io {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

class OutputFileTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / fmt::format("emcalign_output_{}_{}", ::getpid(),
                                                   ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override {
    std::error_code ec;
    fs::permissions(dir_, fs::perms::owner_all, fs::perm_options::add, ec);
    fs::remove_all(dir_, ec);
  }
  std::string path(const std::string& name) const { return (dir_ / name).string(); }
  static std::string slurp(const std::string& p) {
    std::ifstream in(p, std::ios::binary);
    std::stringstream ss;
    ss << in.rdbuf();
    return ss.str();
  }
  std::vector<std::string> entries() const {
    std::vector<std::string> out;
    for (const auto& e : fs::directory_iterator(dir_)) out.push_back(e.path().filename().string());
    std::sort(out.begin(), out.end());
    return out;
  }
  // A process id that no longer runs: a child that has exited and been waited for.
  static pid_t deadPid() {
    const pid_t child = ::fork();
    if (child == 0) ::_exit(0);
    ::waitpid(child, nullptr, 0);
    return child;
  }

  fs::path dir_;
};

TEST_F(OutputFileTest, KindsOfTargets) {
  auto dash = resolveOutput("-");
  ASSERT_TRUE(dash.ok());
  EXPECT_EQ(dash->kind, OutputKind::Stdout);
  auto null = resolveOutput("/dev/null");
  ASSERT_TRUE(null.ok()) << null.error().message;
  EXPECT_EQ(null->kind, OutputKind::Stream);
  ASSERT_EQ(::mkfifo(path("fifo").c_str(), 0600), 0);
  auto fifo = resolveOutput(path("fifo"));
  ASSERT_TRUE(fifo.ok());
  EXPECT_EQ(fifo->kind, OutputKind::Stream);
  auto fresh = resolveOutput(path("new.json"));
  ASSERT_TRUE(fresh.ok());
  EXPECT_EQ(fresh->kind, OutputKind::File);
}

TEST_F(OutputFileTest, RefusedTargetsSayWhy) {
  fs::create_directories(path("d"));
  EXPECT_THAT(resolveOutput(path("d")).error().message, HasSubstr("is a directory"));
  EXPECT_THAT(resolveOutput(path("no/such/x.json")).error().message, HasSubstr("does not exist"));
  EXPECT_THAT(resolveOutput("").error().message, HasSubstr("empty"));
  // Read-only: refused even for root, who could write it (the mode says "keep").
  std::ofstream(path("ro.json")) << "keep";
  fs::permissions(path("ro.json"), fs::perms::owner_read | fs::perms::group_read);
  auto ro = resolveOutput(path("ro.json"));
  ASSERT_FALSE(ro.ok());
  EXPECT_THAT(ro.error().message, HasSubstr("read-only"));
  EXPECT_FALSE(writeOutputFile(path("ro.json"), "new").ok());
  EXPECT_EQ(slurp(path("ro.json")), "keep");
  // A link to nothing.
  fs::create_symlink(path("nothing.json"), path("dangling.json"));
  EXPECT_THAT(resolveOutput(path("dangling.json")).error().message, HasSubstr("which does not exist"));
  // A socket.
  const int fd = ::socket(AF_UNIX, SOCK_STREAM, 0);
  sockaddr_un addr{};
  addr.sun_family = AF_UNIX;
  const std::string sock = path("s");
  ASSERT_LT(sock.size(), sizeof(addr.sun_path));
  std::strcpy(addr.sun_path, sock.c_str());
  ASSERT_EQ(::bind(fd, reinterpret_cast<sockaddr*>(&addr), sizeof(addr)), 0);
  EXPECT_THAT(resolveOutput(sock).error().message, HasSubstr("refusing to write"));
  ::close(fd);
}

TEST_F(OutputFileTest, DevNullStaysADevice) {
  ASSERT_TRUE(writeOutputFile("/dev/null", "a result\n").ok());
  struct stat st {};
  ASSERT_EQ(::stat("/dev/null", &st), 0);
  EXPECT_TRUE(S_ISCHR(st.st_mode));
  // Written in pieces through a temporary elsewhere (as HDF5 needs): still a device.
  auto out = OutputFile::reserve("/dev/null");
  ASSERT_TRUE(out.ok());
  std::ofstream((*out)->writtenPath()) << "binary";
  EXPECT_THAT((*out)->writtenPath(), ::testing::Not(HasSubstr("/dev/")));
  ASSERT_TRUE((*out)->commit().ok());
  EXPECT_FALSE(fs::exists((*out)->writtenPath()));
  ASSERT_EQ(::stat("/dev/null", &st), 0);
  EXPECT_TRUE(S_ISCHR(st.st_mode));
}

TEST_F(OutputFileTest, FifoIsWrittenDirectly) {
  ASSERT_EQ(::mkfifo(path("fifo").c_str(), 0600), 0);
  std::string received;
  std::thread reader([&] { received = slurp(path("fifo")); });
  const Status s = writeOutputFile(path("fifo"), "through the pipe\n");
  reader.join();
  ASSERT_TRUE(s.ok()) << s.error().message;
  EXPECT_EQ(received, "through the pipe\n");
  struct stat st {};
  ASSERT_EQ(::stat(path("fifo").c_str(), &st), 0);
  EXPECT_TRUE(S_ISFIFO(st.st_mode));
}

TEST_F(OutputFileTest, SymbolicLinkIsFollowedAndKept) {
  std::ofstream(path("target.json")) << "old";
  fs::create_symlink("target.json", path("link.json"));
  ASSERT_TRUE(writeOutputFile(path("link.json"), "new").ok());
  EXPECT_TRUE(fs::is_symlink(path("link.json")));
  EXPECT_EQ(slurp(path("target.json")), "new");
  EXPECT_EQ(entries(), (std::vector<std::string>{"link.json", "target.json"}));
}

TEST_F(OutputFileTest, ReplacedFileKeepsItsPermissions) {
  std::ofstream(path("r.json")) << "old";
  fs::permissions(path("r.json"), fs::perms::owner_read | fs::perms::owner_write | fs::perms::group_read);
  ASSERT_TRUE(writeOutputFile(path("r.json"), "new").ok());
  EXPECT_EQ(fs::status(path("r.json")).permissions() & fs::perms::all,
            fs::perms::owner_read | fs::perms::owner_write | fs::perms::group_read);
  EXPECT_EQ(slurp(path("r.json")), "new");
}

TEST_F(OutputFileTest, StaleTemporariesOfDeadProcessesAreRemoved) {
  const std::string stale = path(fmt::format("r.json.tmp-{}", deadPid()));
  const std::string alive = path("r.json.tmp-1");  // init never exits
  const std::string other = path(fmt::format("other.json.tmp-{}", deadPid()));
  for (const auto& p : {stale, alive, other}) std::ofstream(p) << "half a file";
  ASSERT_TRUE(writeOutputFile(path("r.json"), "whole").ok());
  EXPECT_FALSE(fs::exists(stale));
  EXPECT_TRUE(fs::exists(alive)) << "a running process may still be writing it";
  EXPECT_TRUE(fs::exists(other)) << "another target's temporary is not touched";
}

TEST_F(OutputFileTest, RegisteredTemporariesAreRemovedOnDemand) {
  auto out = OutputFile::open(path("r.csv"));
  ASSERT_TRUE(out.ok());
  const std::string tmp = (*out)->writtenPath();
  EXPECT_EQ(tmp, temporaryPathFor(path("r.csv")));
  EXPECT_TRUE(fs::exists(tmp));
  removeTemporaries();  // what the signal handler does
  EXPECT_FALSE(fs::exists(tmp));
  const Status s = (*out)->commit();
  ASSERT_FALSE(s.ok());
  // The system's reason, taken before anything else can change errno (once "… Success").
  EXPECT_THAT(s.error().message,
              HasSubstr("r.csv: cannot rename the temporary file into place: No such file or directory"));
  EXPECT_FALSE(fs::exists(path("r.csv")));
}

TEST_F(OutputFileTest, UncommittedOutputLeavesNothing) {
  std::ofstream(path("r.json")) << "previous";
  {
    auto out = OutputFile::open(path("r.json"));
    ASSERT_TRUE(out.ok());
    std::fputs("half", (*out)->stream());
  }
  EXPECT_EQ(entries(), std::vector<std::string>{"r.json"});
  EXPECT_EQ(slurp(path("r.json")), "previous");
}

TEST_F(OutputFileTest, SecondWriterOfTheSameTargetIsRefused) {
  auto first = OutputFile::open(path("r.json"));
  ASSERT_TRUE(first.ok());
  auto second = OutputFile::open(path("r.json"));
  ASSERT_FALSE(second.ok());
  EXPECT_THAT(second.error().message, HasSubstr("exists"));
  EXPECT_TRUE(fs::exists((*first)->writtenPath())) << "the refused writer must not remove the first one's file";
}

TEST_F(OutputFileTest, OutputsMustDifferFromInputsAndEachOther) {
  std::ofstream(path("ev.csv")) << "events";
  fs::create_symlink("ev.csv", path("link.csv"));
  fs::create_hard_link(path("ev.csv"), path("hard.csv"));
  const std::vector<NamedPath> inputs = {{"", path("ev.csv")}, {"--corrections", ""}};
  EXPECT_THAT(checkDistinct({{"-o", path("ev.csv")}}, inputs).error().message, HasSubstr("same file as the input"));
  EXPECT_THAT(checkDistinct({{"-o", path("link.csv")}}, inputs).error().message, HasSubstr("same file as the input"));
  EXPECT_THAT(checkDistinct({{"-o", path("hard.csv")}}, inputs).error().message, HasSubstr("same file as the input"));
  EXPECT_THAT(
      checkDistinct({{"-o", path("a.json")}, {"--profile-out", dir_.string() + "/./a.json"}}, inputs).error().message,
      HasSubstr("same file as the output -o"));
  EXPECT_TRUE(checkDistinct({{"-o", path("a.json")}, {"--profile-out", path("p.csv")}}, inputs).ok());
  EXPECT_TRUE(checkDistinct({{"-o", "/dev/null"}, {"--profile-out", "/dev/null"}}, inputs).ok());
}

// Standard output redirected onto an input (`-o - >> ev.csv`) is that input; two outputs on one
// stream or pipe would run into each other.
TEST_F(OutputFileTest, StandardOutputOntoAnInputOrTwoOutputsOnOneStreamAreRefused) {
  std::ofstream(path("ev.csv")) << "events";
  const std::vector<NamedPath> inputs = {{"EVENTS", path("ev.csv")}};
  const int saved = ::dup(STDOUT_FILENO);
  ASSERT_GE(saved, 0);
  const auto withStdoutOn = [&](const std::string& file, int flags, auto check) {
    std::fflush(stdout);
    const int fd = ::open(file.c_str(), flags, 0644);
    ASSERT_GE(fd, 0);
    ::dup2(fd, STDOUT_FILENO);
    ::close(fd);
    check();
    std::fflush(stdout);
    ::dup2(saved, STDOUT_FILENO);
  };
  withStdoutOn(path("ev.csv"), O_WRONLY | O_APPEND, [&] {
    auto onInput = checkDistinct({{"-o", "-"}}, inputs);
    ASSERT_FALSE(onInput);
    EXPECT_THAT(onInput.error().message, HasSubstr("-o - (standard output): is the same file as the input EVENTS"));
  });
  withStdoutOn(path("out.txt"), O_WRONLY | O_CREAT | O_TRUNC, [&] {
    EXPECT_TRUE(checkDistinct({{"-o", "-"}}, inputs));
    EXPECT_THAT(checkDistinct({{"-o", "-"}, {"--profile-out", "-"}}, inputs).error().message,
                HasSubstr("give each output its own file"));
    EXPECT_THAT(checkDistinct({{"-o", path("out.txt")}, {"--profile-out", "-"}}, inputs).error().message,
                HasSubstr("is the same file as the output -o"));
  });
  withStdoutOn("/dev/null", O_WRONLY, [&] {
    EXPECT_TRUE(checkDistinct({{"-o", "-"}, {"--profile-out", "-"}}, inputs));
  });
  ::close(saved);
  ASSERT_EQ(::mkfifo(path("fifo").c_str(), 0600), 0);
  EXPECT_THAT(checkDistinct({{"-o", path("fifo")}, {"--profile-out", path("fifo")}}, inputs).error().message,
              HasSubstr("is the same stream as the output -o"));
}

// A directory checked absent is made by the command; failed, it leaves none empty behind (one
// that holds anything, or was there before, is kept).
TEST_F(OutputFileTest, OutputDirectoriesLeftEmptyAreRemovedAndNothingElse) {
  ASSERT_TRUE(checkOutputDirectory(path("made")));
  ASSERT_TRUE(checkOutputDirectory(path("kept")));
  fs::create_directories(path("before"));
  ASSERT_TRUE(checkOutputDirectory(path("before")));
  fs::create_directories(path("made"));
  fs::create_directories(path("kept"));
  std::ofstream(path("kept/result.json")) << "{}";
  removeOutputDirectoriesLeftEmpty();
  EXPECT_FALSE(fs::exists(path("made")));
  EXPECT_TRUE(fs::exists(path("kept/result.json")));
  EXPECT_TRUE(fs::exists(path("before")));
  // A task of a plan keeps them: a sibling task may have just made one to write into.
  ASSERT_TRUE(checkOutputDirectory(path("shared")));
  fs::create_directories(path("shared"));
  keepOutputDirectories();
  removeOutputDirectoriesLeftEmpty();
  EXPECT_TRUE(fs::exists(path("shared")));
}

TEST_F(OutputFileTest, OutputDirectories) {
  EXPECT_TRUE(checkOutputDirectory(path("new/dir")).ok());
  fs::create_directories(path("d"));
  EXPECT_TRUE(checkOutputDirectory(path("d")).ok());
  std::ofstream(path("f")) << "x";
  EXPECT_THAT(checkOutputDirectory(path("f")).error().message, HasSubstr("not a directory"));
}

TEST_F(OutputFileTest, AProtectedInputIsNeverReplaced) {
  std::ofstream(path("events.csv")) << "the input\n";
  fs::create_symlink("events.csv", path("latest.csv"));
  ASSERT_TRUE(writeOutputFile(path("other.csv"), "x"));  // protection off: the caller's choice
  enableInputProtection();
  protectInput({"--events", path("events.csv")});
  for (const char* name : {"events.csv", "latest.csv"}) {
    Status s = writeOutputFile(path(name), "overwritten");
    ASSERT_FALSE(s) << name;
    EXPECT_THAT(s.error().message, HasSubstr("same file as the input --events"));
  }
  fs::create_hard_link(path("events.csv"), path("hard.csv"));
  EXPECT_FALSE(writeOutputFile(path("hard.csv"), "overwritten"));
  EXPECT_FALSE(OutputFile::reserve(path("latest.csv")));  // an HDF5 writer's way in
  EXPECT_EQ(slurp(path("events.csv")), "the input\n");
  EXPECT_TRUE(writeOutputFile(path("other.csv"), "y"));  // anything else still written
  // A name met first without an option takes the option it is given later.
  protectInput({"", path("other.csv")});
  protectInput({"--detector", path("other.csv")});
  EXPECT_THAT(writeOutputFile(path("other.csv"), "z").error().message, HasSubstr("the input --detector"));
  disableInputProtection();
  EXPECT_TRUE(writeOutputFile(path("other.csv"), "z"));
}

TEST_F(OutputFileTest, AnOutputDirectoryHoldingALinkToAnInputIsRefused) {
  std::ofstream(path("c.db")) << "database";
  fs::create_directories(path("out/plots"));
  std::ofstream(path("out/kept.json")) << "{}";
  const std::vector<NamedPath> inputs = {{"--conditions", path("c.db")}, {"--events", path("out/kept.json")}};
  // An input inside the output directory, under its own name, is not a planted link.
  EXPECT_TRUE(checkDirectoryHoldsNoInput({"-o", path("out")}, inputs));
  fs::create_symlink("../../c.db", path("out/plots/trend.png"));
  Status s = checkDirectoryHoldsNoInput({"-o", path("out")}, inputs);
  ASSERT_FALSE(s);
  EXPECT_THAT(s.error().message, HasSubstr("is a link to the input --conditions"));
  EXPECT_THAT(s.error().message, HasSubstr("trend.png"));
  fs::remove(path("out/plots/trend.png"));
  fs::create_hard_link(path("c.db"), path("out/trend.json"));
  Status h = checkDirectoryHoldsNoInput({"-o", path("out")}, inputs);
  ASSERT_FALSE(h);
  EXPECT_THAT(h.error().message, HasSubstr("hard link"));
  EXPECT_TRUE(checkDirectoryHoldsNoInput({"-o", path("absent")}, inputs));
}

TEST_F(OutputFileTest, TemporaryNames) {
  for (const char* name : {"r.json.tmp-123", "corrected.h5.tmp-77.tmp-77", ".corrected-4242.h5"}) {
    EXPECT_TRUE(isTemporaryName(name)) << name;
  }
  for (const char* name : {"run_1.h5", ".tmp-12", "r.json.tmp-", "r.json.tmp-12a", "notes.tmp-x.h5", ".corrected-.h5",
                           ".corrected-12.csv"}) {
    EXPECT_FALSE(isTemporaryName(name)) << name;
  }
  EXPECT_EQ(temporaryWriter("corrected.h5.tmp-77.tmp-78"), 77);
  EXPECT_EQ(temporaryWriter(".corrected-4242.h5"), 4242);
}

TEST_F(OutputFileTest, ANestedTemporaryOfADeadWriterIsRemoved) {
  const pid_t dead = deadPid();
  std::ofstream(path(fmt::format("corrected.h5.tmp-{}.tmp-{}", dead, dead))) << "half";
  std::ofstream(path(fmt::format("corrected.h5.tmp-{}", dead))) << "half";
  auto out = OutputFile::reserve(path("corrected.h5"));
  ASSERT_TRUE(out) << out.error().message;
  EXPECT_EQ(entries(), std::vector<std::string>{});
}

}  // namespace
}  // namespace emcalign::io
