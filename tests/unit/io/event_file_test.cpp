#include "emcalign/io/event_file.hpp"

#include <unistd.h>

#include <atomic>
#include <bit>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <numbers>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <fmt/format.h>
#include <gmock/gmock.h>
#include <gtest/gtest.h>

// The malformed-HDF5 tests build broken files with the HDF5 C API itself (the library's
// writer refuses to write them). emcalign_io links HDF5, so the symbols are there; Debian
// keeps the header under hdf5/serial.
#if __has_include(<hdf5.h>)
#include <hdf5.h>
#else
#include <hdf5/serial/hdf5.h>
#endif

namespace emcalign::io {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;
using ::testing::Not;

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kPi = std::numbers::pi;

ParticleRow chargedRow(std::int32_t run, std::int64_t event, double beam, double z0, double rho, double phi,
                       double theta, double energy, double phiEmc, double thetaEmc) {
  ParticleRow r;
  r.run = run;
  r.event = event;
  r.beamEnergy = beam;
  r.muonVeto = 0;
  r.charged = 1;
  r.z0 = z0;
  r.rho = rho;
  r.phiTs = phi;
  r.thetaTs = theta;
  r.energy = energy;
  r.phiEmc = phiEmc;
  r.thetaEmc = thetaEmc;
  return r;
}

ParticleRow photonRow(std::int32_t run, std::int64_t event, double beam, double energy, double phiEmc,
                      double thetaEmc) {
  ParticleRow r = chargedRow(run, event, beam, kNaN, kNaN, kNaN, kNaN, energy, phiEmc, thetaEmc);
  r.charged = 0;
  return r;
}

// Events of 2, 3 and 4 rows with awkward values: NaN clusters, 0.1, tiny and huge numbers,
// angles exactly on the bounds, negative zero, 64-bit event numbers.
std::vector<ParticleRow> sampleRows(int events, std::int32_t run = 1, std::int64_t firstEvent = 0) {
  std::vector<ParticleRow> rows;
  for (int e = 0; e < events; ++e) {
    const std::int64_t event = firstEvent + e;
    const double beam = 508.0 + 0.1 * e;
    const int size = 2 + e % 3;
    for (int i = 0; i < size; ++i) {
      const double t = 0.001 * ((e * 7 + i) % 500);  // keeps the angles in range
      if (i == 2) {
        rows.push_back(photonRow(run, event, beam, 1e-300 + t, 2.0 * kPi, kPi));
      } else if (i == 3) {
        rows.push_back(chargedRow(run, event, beam, -0.0, 0.1, 0.0, 0.0, kNaN, kNaN, kNaN));
      } else {
        rows.push_back(chargedRow(run, event, beam, -3.25 + t, 0.1 + t, 1.0 / 3.0 + t, kPi / 2 + t, beam * (0.9 + t),
                                  1.0 / 3.0 + 2 * t, kPi / 2 - t));
      }
      rows.back().muonVeto = static_cast<std::int8_t>(e % 2);
    }
  }
  return rows;
}

std::vector<TruthRow> sampleTruth(std::size_t n) {
  std::vector<TruthRow> truth(n);
  for (std::size_t i = 0; i < n; ++i) {
    const double t = static_cast<double>(i);
    truth[i].pdg = i % 3 == 2 ? 22 : (i % 2 ? 11 : -11);
    truth[i].energy = 508.0 + t / 7.0;
    truth[i].theta = 0.5 + t / 1e5;
    truth[i].phi = 1.5 - t / 1e5;
    truth[i].vertex = Vec3(0.01 * t, -0.02, 1.0 / 3.0);
    truth[i].showerCentre = i % 4 == 3 ? Vec3(kNaN, kNaN, kNaN) : Vec3(30.0 + t, -t, 0.1 * t);
  }
  return truth;
}

bool sameDouble(double a, double b) {
  return (std::isnan(a) && std::isnan(b)) || std::bit_cast<std::uint64_t>(a) == std::bit_cast<std::uint64_t>(b);
}

void expectSameRows(const std::vector<ParticleRow>& a, const std::vector<ParticleRow>& b) {
  ASSERT_EQ(a.size(), b.size());
  for (std::size_t i = 0; i < a.size(); ++i) {
    SCOPED_TRACE(fmt::format("row {}", i));
    EXPECT_EQ(a[i].run, b[i].run);
    EXPECT_EQ(a[i].event, b[i].event);
    EXPECT_EQ(a[i].muonVeto, b[i].muonVeto);
    EXPECT_EQ(a[i].charged, b[i].charged);
    const double va[] = {a[i].beamEnergy, a[i].z0,     a[i].rho,    a[i].phiTs,
                         a[i].thetaTs,    a[i].energy, a[i].phiEmc, a[i].thetaEmc};
    const double vb[] = {b[i].beamEnergy, b[i].z0,     b[i].rho,    b[i].phiTs,
                         b[i].thetaTs,    b[i].energy, b[i].phiEmc, b[i].thetaEmc};
    for (int c = 0; c < 8; ++c)
      EXPECT_TRUE(sameDouble(va[c], vb[c])) << "field " << c << ": " << va[c] << " vs " << vb[c];
  }
}

void expectSameTruth(const std::vector<TruthRow>& a, const std::vector<TruthRow>& b) {
  ASSERT_EQ(a.size(), b.size());
  for (std::size_t i = 0; i < a.size(); ++i) {
    SCOPED_TRACE(fmt::format("truth row {}", i));
    EXPECT_EQ(a[i].pdg, b[i].pdg);
    EXPECT_TRUE(sameDouble(a[i].energy, b[i].energy));
    EXPECT_TRUE(sameDouble(a[i].theta, b[i].theta));
    EXPECT_TRUE(sameDouble(a[i].phi, b[i].phi));
    for (int k = 0; k < 3; ++k) {
      EXPECT_TRUE(sameDouble(a[i].vertex[k], b[i].vertex[k]));
      EXPECT_TRUE(sameDouble(a[i].showerCentre[k], b[i].showerCentre[k]));
    }
  }
}

std::string readBytes(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

void writeBytes(const fs::path& p, const std::string& text) {
  std::ofstream out(p, std::ios::binary | std::ios::trunc);
  out << text;
}

struct ReadBack {
  std::vector<ParticleRow> rows;
  std::vector<TruthRow> truth;
  bool hadTruth = false;
  std::vector<std::pair<std::string, std::string>> attributes;
  std::vector<std::size_t> blockSizes;
};

Result<ReadBack> readAll(const std::vector<std::string>& paths, std::size_t blockRows = 65536) {
  auto reader = EventReader::open(paths, ReaderOptions{blockRows});
  if (!reader) return reader.error();
  ReadBack out;
  std::vector<ParticleRow> block;
  while (true) {
    auto more = (*reader)->next(block);
    if (!more) return more.error();
    if (!*more) break;
    out.rows.insert(out.rows.end(), block.begin(), block.end());
    out.blockSizes.push_back(block.size());
    if (const auto* truth = (*reader)->truth()) {
      out.hadTruth = true;
      EXPECT_EQ(truth->size(), block.size());
      out.truth.insert(out.truth.end(), truth->begin(), truth->end());
    }
    out.attributes = (*reader)->attributes();
  }
  return out;
}

Status writeFile(const std::string& path, const std::vector<ParticleRow>& rows, WriterOptions options = {},
                 const std::vector<TruthRow>& truth = {}, const std::vector<Hit>& hits = {}) {
  auto writer = EventWriter::open(path, std::move(options));
  if (!writer) return writer.error();
  if (auto s = (*writer)->append(rows, truth, hits); !s) return s;
  return (*writer)->close();
}

class EventFile : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    dir_ = fs::temp_directory_path() /
           fmt::format("emcalign-event-file-{}-{}", static_cast<long>(::getpid()), info->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  std::string path(const std::string& name) const { return (dir_ / name).string(); }

  std::vector<std::string> filesInDir() const {
    std::vector<std::string> names;
    for (const auto& entry : fs::directory_iterator(dir_)) names.push_back(entry.path().filename().string());
    return names;
  }

  // The error of reading a file whose text is `text`; the file is called `name`.
  std::string csvError(const std::string& text, const std::string& name = "bad.csv") {
    writeBytes(path(name), text);
    auto r = readAll({path(name)}, 4);
    EXPECT_FALSE(r.ok()) << "accepted:\n" << text;
    return r.ok() ? "" : r.error().message;
  }

  fs::path dir_;
};

const std::vector<std::pair<std::string, std::string>> kAttributes = {
    {"truth_parameters", R"({"format":"emcalign-alignment/1","parameters":{"alpha":3.0}})"},
    {"generator", "bhabha seed=42"},
    {"empty", ""},
    {"a.b-c_d", "  leading and trailing spaces  "}};

// ------------------------------------------------------------------------------ round trip

TEST_F(EventFile, CsvRoundTripIsExact) {
  const auto rows = sampleRows(30);
  ASSERT_TRUE(writeFile(path("e.csv"), rows, {true, kAttributes}, sampleTruth(rows.size())).ok());
  auto back = readAll({path("e.csv")});
  ASSERT_TRUE(back.ok()) << back.error().message;
  expectSameRows(back->rows, rows);
  EXPECT_EQ(back->attributes, kAttributes);
  EXPECT_FALSE(back->hadTruth) << "CSV carries no truth";
  EXPECT_EQ(filesInDir(), std::vector<std::string>{"e.csv"}) << "no temporary left behind";
}

TEST_F(EventFile, CsvTextFormat) {
  std::vector<ParticleRow> rows = {chargedRow(3, 9000000000, 508, 0.5, 0.1, 1, 1.5, kNaN, kNaN, kNaN),
                                   photonRow(3, 9000000000, 508, 200, 3, 2)};
  rows[0].muonVeto = rows[1].muonVeto = 1;
  ASSERT_TRUE(writeFile(path("t.csv"), rows, {false, {{"generator", "{\"seed\":1}"}}}).ok());
  EXPECT_EQ(readBytes(path("t.csv")),
            "# generator: {\"seed\":1}\n"
            "run,event,beam_energy_mev,muon_veto,charged,z0_cm,rho_cm,phi_ts_rad,theta_ts_rad,energy_mev,"
            "phi_emc_rad,theta_emc_rad\n"
            "3,9000000000,508,1,1,0.5,0.10000000000000001,1,1.5,,,\n"
            "3,9000000000,508,1,0,,,,,200,3,2\n");
  EXPECT_EQ(std::string(kCsvHeader) + "\n",
            "run,event,beam_energy_mev,muon_veto,charged,z0_cm,rho_cm,phi_ts_rad,theta_ts_rad,energy_mev,"
            "phi_emc_rad,theta_emc_rad\n");
}

TEST_F(EventFile, CsvAcceptsCommentsBlankLinesAndCrlf) {
  const std::string text = "# a plain comment\r\n# source: hand-written\r\n\r\n" + std::string(kCsvHeader) +
                           "\r\n1,7,508,0,1,0.5,0.1,1,1.5,480,1.01,1.49\r\n# between rows\r\n\r\n"
                           "1,7,508,0,0,,,,,200,3.0,2.0\r\n# a last comment without newline";
  writeBytes(path("h.csv"), text);
  auto back = readAll({path("h.csv")});
  ASSERT_TRUE(back.ok()) << back.error().message;
  ASSERT_EQ(back->rows.size(), 2u);
  EXPECT_EQ(back->rows[1].energy, 200.0);
  const std::vector<std::pair<std::string, std::string>> attributes = {{"source", "hand-written"}};
  EXPECT_EQ(back->attributes, attributes);
}

TEST_F(EventFile, CsvHeaderOnlyHasNoRows) {
  writeBytes(path("h.csv"), std::string(kCsvHeader) + "\n");
  auto back = readAll({path("h.csv")});
  ASSERT_TRUE(back.ok()) << back.error().message;
  EXPECT_TRUE(back->rows.empty());
}

TEST_F(EventFile, Hdf5RoundTripWithTruthIsExact) {
  const auto rows = sampleRows(7000);  // > one 16384-row chunk
  const auto truth = sampleTruth(rows.size());
  ASSERT_GT(rows.size(), 16384u);
  auto writer = EventWriter::open(path("e.h5"), {true, kAttributes});
  ASSERT_TRUE(writer.ok()) << writer.error().message;
  for (std::size_t i = 0; i < rows.size(); i += 5000) {  // appends of any size
    const std::size_t n = std::min<std::size_t>(5000, rows.size() - i);
    auto s = (*writer)->append(std::span(rows).subspan(i, n), std::span(truth).subspan(i, n));
    ASSERT_TRUE(s.ok()) << s.error().message;
  }
  ASSERT_TRUE((*writer)->close().ok());
  auto back = readAll({path("e.h5")});
  ASSERT_TRUE(back.ok()) << back.error().message;
  expectSameRows(back->rows, rows);
  ASSERT_TRUE(back->hadTruth);
  expectSameTruth(back->truth, truth);
  EXPECT_EQ(back->attributes, kAttributes) << "attributes keep their order";
  EXPECT_EQ(filesInDir(), std::vector<std::string>{"e.h5"});
}

// Debian's libhdf5 is the serial build, and the reader forks: a thread writing HDF5 while
// another opens a reader must neither race inside HDF5 nor hand the forked reader HDF5's
// state half-changed (it then waited for a lock nobody would release, and the file was
// reported unreadable after the timeout). Every open below has 10 s; an open normally takes
// milliseconds.
TEST_F(EventFile, Hdf5ReadWhileAnotherThreadWrites) {
#if defined(__SANITIZE_ADDRESS__)
  // GCC 12's libasan does not hold its allocator's lock across fork (LLVM's runtime does
  // since 2024): a fork while the writing thread allocates leaves the child waiting for it
  // forever (google/sanitizers#1814). glibc's malloc is fork-safe; the release stage runs this.
  GTEST_SKIP() << "ASan's allocator is not fork-safe in GCC 12";
#endif
  const auto rows = sampleRows(3000);
  const auto truth = sampleTruth(rows.size());
  ASSERT_TRUE(writeFile(path("in.h5"), rows, {true, kAttributes}, truth).ok());
  std::atomic<bool> writing{true};
  std::atomic<int> writes{0};
  std::string writeError;
  std::thread writer([&] {
    for (int i = 0; writing && i < 1000; ++i) {
      if (Status s = writeFile(path(fmt::format("out{}.h5", i % 2)), rows, {true, kAttributes}, truth); !s) {
        writeError = s.error().message;
        return;
      }
      ++writes;
    }
  });
  ReaderOptions o{65536};
  o.hdf5TimeoutSeconds = 10.0;
  std::string readError;
  for (int k = 0; k < 40 && readError.empty(); ++k) {
    auto reader = EventReader::open({path("in.h5")}, o);
    std::vector<ParticleRow> block;
    std::size_t n = 0;
    while (reader.ok()) {
      auto more = (*reader)->next(block);
      if (!more) readError = fmt::format("read {}: {}", k, more.error().message);
      if (!more || !*more) break;
      n += block.size();
    }
    if (!reader) readError = fmt::format("open {}: {}", k, reader.error().message);
    if (readError.empty() && n != rows.size()) readError = fmt::format("read {}: {} rows", k, n);
  }
  writing = false;
  writer.join();
  EXPECT_EQ(readError, "");
  EXPECT_EQ(writeError, "");
  EXPECT_GT(writes.load(), 0);
  auto back = readAll({path("out0.h5")});
  ASSERT_TRUE(back.ok()) << back.error().message;
  expectSameRows(back->rows, rows);
}

TEST_F(EventFile, Hdf5WithoutTruthHasNoTruth) {
  const auto rows = sampleRows(10);
  std::vector<std::pair<std::string, std::string>> attributes = {{"note", "two\nlines are fine in HDF5"}};
  ASSERT_TRUE(writeFile(path("e.hdf5"), rows, {false, attributes}).ok());
  auto reader = EventReader::open({path("e.hdf5")});
  ASSERT_TRUE(reader.ok()) << reader.error().message;
  EXPECT_EQ((*reader)->attributes(), attributes) << "attributes are available right after open";
  std::vector<ParticleRow> block;
  auto more = (*reader)->next(block);
  ASSERT_TRUE(more.ok() && *more);
  EXPECT_EQ((*reader)->truth(), nullptr);
  expectSameRows(block, rows);
  more = (*reader)->next(block);
  ASSERT_TRUE(more.ok());
  EXPECT_FALSE(*more);
  EXPECT_TRUE(block.empty());
}

TEST_F(EventFile, Hdf5EmptyFile) {
  ASSERT_TRUE(writeFile(path("e.h5"), {}, {true, {}}).ok());
  auto back = readAll({path("e.h5")});
  ASSERT_TRUE(back.ok()) << back.error().message;
  EXPECT_TRUE(back->rows.empty());
}

// The layout other tools (h5py, h5dump) see: /events/<column> 1-D, chunked 16384,
// unlimited, shuffle + deflate 4, no object times.
TEST_F(EventFile, Hdf5Layout) {
  const auto rows = sampleRows(5);
  ASSERT_TRUE(writeFile(path("e.h5"), rows, {true, kAttributes}, sampleTruth(rows.size())).ok());
  const hid_t file = H5Fopen(path("e.h5").c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  ASSERT_GE(file, 0);
  const auto check = [&](const std::string& name, hid_t expectedType) {
    SCOPED_TRACE(name);
    const hid_t ds = H5Dopen2(file, name.c_str(), H5P_DEFAULT);
    ASSERT_GE(ds, 0);
    const hid_t type = H5Dget_type(ds);
    EXPECT_GT(H5Tequal(type, expectedType), 0);
    const hid_t space = H5Dget_space(ds);
    hsize_t dims = 0, maxDims = 0;
    EXPECT_EQ(H5Sget_simple_extent_dims(space, &dims, &maxDims), 1);
    EXPECT_EQ(dims, rows.size());
    EXPECT_EQ(maxDims, H5S_UNLIMITED);
    const hid_t dcpl = H5Dget_create_plist(ds);
    hsize_t chunk = 0;
    EXPECT_EQ(H5Pget_chunk(dcpl, 1, &chunk), 1);
    EXPECT_EQ(chunk, 16384u);
    ASSERT_EQ(H5Pget_nfilters(dcpl), 2);
    unsigned flags = 0, level = 0;
    std::size_t nElements = 1;
    EXPECT_EQ(H5Pget_filter2(dcpl, 0, &flags, &nElements, &level, 0, nullptr, nullptr), H5Z_FILTER_SHUFFLE);
    nElements = 1;
    EXPECT_EQ(H5Pget_filter2(dcpl, 1, &flags, &nElements, &level, 0, nullptr, nullptr), 32004)
        << "LZ4, the filter of Debian's hdf5-filter-plugin";
    // No modification time recorded (H5Pget_obj_track_times of a reopened v1 object
    // header always says true; the stored time is what matters).
    H5O_info_t info;
    ASSERT_GE(H5Oget_info2(ds, &info, H5O_INFO_TIME), 0);
    EXPECT_EQ(info.mtime, 0);
    EXPECT_EQ(info.ctime, 0);
    H5Pclose(dcpl);
    H5Sclose(space);
    H5Tclose(type);
    H5Dclose(ds);
  };
  check("/events/run", H5T_STD_I32LE);
  check("/events/event", H5T_STD_I64LE);
  check("/events/beam_energy_mev", H5T_IEEE_F64LE);
  check("/events/muon_veto", H5T_STD_I8LE);
  check("/events/charged", H5T_STD_I8LE);
  for (const char* name :
       {"z0_cm", "rho_cm", "phi_ts_rad", "theta_ts_rad", "energy_mev", "phi_emc_rad", "theta_emc_rad"}) {
    check(fmt::format("/events/{}", name), H5T_IEEE_F64LE);
  }
  check("/truth/pdg", H5T_STD_I32LE);
  for (const char* name : {"energy_mev", "theta_rad", "phi_rad", "vertex_x_cm", "vertex_y_cm", "vertex_z_cm",
                           "shower_x_cm", "shower_y_cm", "shower_z_cm"}) {
    check(fmt::format("/truth/{}", name), H5T_IEEE_F64LE);
  }
  for (const char* group : {"/", "/events", "/truth"}) {
    SCOPED_TRACE(group);
    H5O_info_t info;
    ASSERT_GE(H5Oget_info_by_name2(file, group, &info, H5O_INFO_TIME, H5P_DEFAULT), 0);
    EXPECT_EQ(info.mtime, 0);
  }
  H5Fclose(file);
}

TEST_F(EventFile, Hdf5IsByteIdenticalOnRewrite) {
  const auto rows = sampleRows(7000);
  const auto truth = sampleTruth(rows.size());
  ASSERT_TRUE(writeFile(path("a.h5"), rows, {true, kAttributes}, truth).ok());
  // Something else in between, so that reused memory differs between the two writes.
  ASSERT_TRUE(writeFile(path("other.h5"), sampleRows(100, 5), {false, {{"x", "y"}}}).ok());
  {
    auto writer = EventWriter::open(path("b.h5"), {true, kAttributes});
    ASSERT_TRUE(writer.ok());
    for (std::size_t i = 0; i < rows.size(); i += 777) {  // other append sizes, same file
      const std::size_t n = std::min<std::size_t>(777, rows.size() - i);
      ASSERT_TRUE((*writer)->append(std::span(rows).subspan(i, n), std::span(truth).subspan(i, n)).ok());
    }
    ASSERT_TRUE((*writer)->close().ok());
  }
  const std::string a = readBytes(path("a.h5"));
  const std::string b = readBytes(path("b.h5"));
  ASSERT_FALSE(a.empty());
  EXPECT_EQ(a.size(), b.size());
  EXPECT_TRUE(a == b) << "the HDF5 files differ";
}

TEST_F(EventFile, CsvIsByteIdenticalOnRewrite) {
  const auto rows = sampleRows(50);
  ASSERT_TRUE(writeFile(path("a.csv"), rows, {false, kAttributes}).ok());
  ASSERT_TRUE(writeFile(path("b.csv"), rows, {false, kAttributes}).ok());
  EXPECT_EQ(readBytes(path("a.csv")), readBytes(path("b.csv")));
}

// ----------------------------------------------------------------------- blocks and files

TEST_F(EventFile, BlocksEndAtEventBoundariesAcrossFiles) {
  constexpr std::size_t kBlock = 3;
  const auto rowsA = sampleRows(11, 1, 0);    // events of 2, 3, 4 rows
  const auto rowsB = sampleRows(13, 2, 100);  // in another run
  ASSERT_TRUE(writeFile(path("a.csv"), rowsA, {false, {{"file", "a"}}}).ok());
  ASSERT_TRUE(writeFile(path("b.h5"), rowsB, {true, {{"file", "b"}}}, sampleTruth(rowsB.size())).ok());

  auto reader = EventReader::open({path("a.csv"), path("b.h5")}, ReaderOptions{kBlock});
  ASSERT_TRUE(reader.ok()) << reader.error().message;
  std::vector<ParticleRow> all, block;
  std::vector<TruthRow> truthB;
  std::vector<std::string> blockFiles;
  while (true) {
    auto more = (*reader)->next(block);
    ASSERT_TRUE(more.ok()) << more.error().message;
    if (!*more) break;
    ASSERT_FALSE(block.empty());
    const std::string file = (*reader)->attributes().at(0).second;
    blockFiles.push_back(file);
    // Whole events only: the last event of a block starts before kBlock rows (else the
    // block would have ended before it), and the next block starts a new event.
    std::size_t lastStart = block.size() - 1;
    while (lastStart > 0 && block[lastStart - 1].event == block.back().event) --lastStart;
    EXPECT_LT(lastStart, kBlock);
    if (!all.empty() && blockFiles.size() > 1 && blockFiles[blockFiles.size() - 2] == file) {
      EXPECT_NE(all.back().event, block.front().event) << "an event was split between blocks";
      EXPECT_GE(all.size(), kBlock);
    }
    for (std::size_t i = 1; i < block.size(); ++i) {
      EXPECT_EQ(block[i].run, block[0].run) << "a block never spans two files";
    }
    if (file == "b") {
      ASSERT_NE((*reader)->truth(), nullptr);
      ASSERT_EQ((*reader)->truth()->size(), block.size());
      truthB.insert(truthB.end(), (*reader)->truth()->begin(), (*reader)->truth()->end());
    } else {
      EXPECT_EQ((*reader)->truth(), nullptr);
    }
    all.insert(all.end(), block.begin(), block.end());
  }
  auto expected = rowsA;
  expected.insert(expected.end(), rowsB.begin(), rowsB.end());
  expectSameRows(all, expected);
  expectSameTruth(truthB, sampleTruth(rowsB.size()));
  EXPECT_GT(blockFiles.size(), 10u);
  // Every block but the last of each file holds at least kBlock rows.
  std::size_t sum = 0;
  auto back = readAll({path("a.csv")}, kBlock);
  ASSERT_TRUE(back.ok());
  for (std::size_t i = 0; i + 1 < back->blockSizes.size(); ++i) EXPECT_GE(back->blockSizes[i], kBlock);
  for (auto n : back->blockSizes) sum += n;
  EXPECT_EQ(sum, rowsA.size());
}

TEST_F(EventFile, OneEventLargerThanTheBlockStaysWhole) {
  std::vector<ParticleRow> rows;
  for (int i = 0; i < 10; ++i) rows.push_back(photonRow(1, 5, 508, 10 + i, 1, 1));
  rows.push_back(photonRow(1, 6, 508, 10, 1, 1));
  ASSERT_TRUE(writeFile(path("e.h5"), rows).ok());
  auto back = readAll({path("e.h5")}, 3);
  ASSERT_TRUE(back.ok()) << back.error().message;
  EXPECT_EQ(back->blockSizes, (std::vector<std::size_t>{10, 1}));
}

// ------------------------------------------------------------------------------- writers

TEST_F(EventFile, WriterDestroyedWithoutCloseLeavesNothing) {
  for (const char* name : {"e.csv", "e.h5"}) {
    SCOPED_TRACE(name);
    {
      auto writer = EventWriter::open(path(name), {true, kAttributes});
      ASSERT_TRUE(writer.ok()) << writer.error().message;
      const auto rows = sampleRows(20);
      ASSERT_TRUE((*writer)->append(rows, sampleTruth(rows.size())).ok());
      EXPECT_EQ(filesInDir().size(), 1u) << "the temporary exists while writing";
      EXPECT_FALSE(fs::exists(path(name))) << "the target appears only on close";
    }
    EXPECT_TRUE(filesInDir().empty());
  }
}

TEST_F(EventFile, WriterTemporaryIsNamedAfterTheTarget) {
  auto writer = EventWriter::open(path("e.h5"), {});
  ASSERT_TRUE(writer.ok());
  EXPECT_EQ(filesInDir(), std::vector<std::string>{fmt::format("e.h5.tmp-{}", static_cast<long>(::getpid()))});
}

TEST_F(EventFile, WriterRefusesBadRowsAndLeavesNothing) {
  for (const char* name : {"e.csv", "e.h5"}) {
    SCOPED_TRACE(name);
    {
      auto writer = EventWriter::open(path(name), {});
      ASSERT_TRUE(writer.ok());
      auto rows = sampleRows(3);
      rows[4].phiEmc = 7.0;
      auto s = (*writer)->append(rows, {});
      ASSERT_FALSE(s.ok());
      EXPECT_THAT(s.error().message, HasSubstr(name));
      EXPECT_THAT(s.error().message, HasSubstr("row 4"));
      EXPECT_THAT(s.error().message, HasSubstr("phi_emc_rad"));
      auto c = (*writer)->close();
      EXPECT_FALSE(c.ok()) << "a writer that refused rows does not produce a file";
    }
    EXPECT_TRUE(filesInDir().empty());
  }
}

TEST_F(EventFile, WriterChecksEventConsistencyAcrossAppends) {
  auto writer = EventWriter::open(path("e.csv"), {});
  ASSERT_TRUE(writer.ok());
  const std::vector<ParticleRow> first = {photonRow(1, 1, 508, 10, 1, 1)};
  const std::vector<ParticleRow> second = {photonRow(1, 1, 509, 10, 1, 1)};
  ASSERT_TRUE((*writer)->append(first, {}).ok());
  auto s = (*writer)->append(second, {});
  ASSERT_FALSE(s.ok());
  EXPECT_THAT(s.error().message, HasSubstr("beam_energy_mev"));
}

TEST_F(EventFile, WriterNeedsOneTruthRowPerRow) {
  auto writer = EventWriter::open(path("e.h5"), {true, {}});
  ASSERT_TRUE(writer.ok());
  const auto rows = sampleRows(2);
  auto s = (*writer)->append(rows, sampleTruth(rows.size() - 1));
  ASSERT_FALSE(s.ok());
  EXPECT_THAT(s.error().message, HasSubstr("truth"));
}

TEST_F(EventFile, WriterRefusesAttributesACsvCannotHold) {
  auto w = EventWriter::open(path("e.csv"), {false, {{"generator", "line one\nline two"}}});
  ASSERT_FALSE(w.ok());
  EXPECT_THAT(w.error().message, HasSubstr("e.csv"));
  EXPECT_THAT(w.error().message, HasSubstr("generator"));
  for (const char* key : {"", "has space", "colon:", "a\nb"}) {
    auto bad = EventWriter::open(path("e.h5"), {false, {{key, "v"}}});
    EXPECT_FALSE(bad.ok()) << key;
  }
  auto twice = EventWriter::open(path("e.h5"), {false, {{"k", "1"}, {"k", "2"}}});
  ASSERT_FALSE(twice.ok());
  EXPECT_THAT(twice.error().message, HasSubstr("twice"));
  EXPECT_TRUE(filesInDir().empty());
}

TEST_F(EventFile, WriterIntoMissingDirectoryFails) {
  for (const char* name : {"no/such/dir/e.csv", "no/such/dir/e.h5"}) {
    auto w = EventWriter::open(path(name), {});
    ASSERT_FALSE(w.ok());
    EXPECT_THAT(w.error().message, HasSubstr(name));
  }
}

TEST_F(EventFile, WriterCannotBeUsedAfterClose) {
  auto writer = EventWriter::open(path("e.csv"), {});
  ASSERT_TRUE(writer.ok());
  ASSERT_TRUE((*writer)->close().ok());
  EXPECT_FALSE((*writer)->append(sampleRows(1), {}).ok());
  EXPECT_FALSE((*writer)->close().ok());
  EXPECT_TRUE(fs::exists(path("e.csv")));
}

TEST(EventFileFormat, ChosenByName) {
  EXPECT_EQ(formatOf("a/b.csv"), EventFormat::Csv);
  EXPECT_EQ(formatOf("b.h5"), EventFormat::Hdf5);
  EXPECT_EQ(formatOf("b.hdf5"), EventFormat::Hdf5);
  EXPECT_EQ(formatOf("b.csv.h5"), EventFormat::Hdf5);
  EXPECT_EQ(formatOf("csv"), EventFormat::Hdf5);
}

// --------------------------------------------------------------------------- CSV errors

const std::string kHeader = std::string(kCsvHeader) + "\n";
const std::string kGoodCharged = "1,7,508,0,1,0.5,0.1,1,1.5,480,1.01,1.49\n";

struct CsvCase {
  const char* body;    // after the header line (line 1)
  const char* where;   // "line N"
  const char* column;  // the column named
  const char* reason;  // a word of the reason
};

TEST_F(EventFile, CsvRowErrorsNameFileLineAndColumn) {
  const CsvCase cases[] = {
      {"1,7,508,0,1,abc,0.1,1,1.5,480,1,1.5\n", "line 2", "z0_cm", "not a finite number"},
      {"1,7,508,0,1,0.5,0.1,1,1.5,nan,1,1.5\n", "line 2", "energy_mev", "'nan' is not allowed"},
      {"1,7,508,0,1,0.5,-inf,1,1.5,480,1,1.5\n", "line 2", "rho_cm", "'-inf' is not allowed"},
      {"1,7,508,0,1,0.5,0.1,1,1.5,480,1,1e999\n", "line 2", "theta_emc_rad", "not a finite"},
      {"1.5,7,508,0,1,0.5,0.1,1,1.5,480,1,1.5\n", "line 2", "'run'", "not an integer"},
      {",7,508,0,1,0.5,0.1,1,1.5,480,1,1.5\n", "line 2", "'run'", "empty"},
      {"3000000000,7,508,0,1,0.5,0.1,1,1.5,480,1,1.5\n", "line 2", "'run'", "outside"},
      {"1,2e3,508,0,1,0.5,0.1,1,1.5,480,1,1.5\n", "line 2", "'event'", "not an integer"},
      {"1,99999999999999999999,508,0,1,0.5,0.1,1,1.5,480,1,1.5\n", "line 2", "'event'", "out of range"},
      {"1,7,508,0.5,1,0.5,0.1,1,1.5,480,1,1.5\n", "line 2", "muon_veto", "not an integer"},
      {"1,7,508,2,1,0.5,0.1,1,1.5,480,1,1.5\n", "line 2", "muon_veto", "outside [0, 1]"},
      {"1,7,508,0,x,0.5,0.1,1,1.5,480,1,1.5\n", "line 2", "charged", "not a finite number"},
      {"1,7,508,0,3,0.5,0.1,1,1.5,480,1,1.5\n", "line 2", "charged", "outside [0, 1]"},
      {"1,7,508,0,-1,0.5,0.1,1,1.5,480,1,1.5\n", "line 2", "charged", "outside [0, 1]"},
      {"1,7,508,0,1,0.5,0.1,7,1.5,480,1,1.5\n", "line 2", "phi_ts_rad", "outside [0, 2*pi]"},
      {"1,7,508,0,1,0.5,0.1,1,-0.1,480,1,1.5\n", "line 2", "theta_ts_rad", "outside [0, pi]"},
      {"1,7,508,0,1,0.5,0.1,1,1.5,480,-1,1.5\n", "line 2", "phi_emc_rad", "outside [0, 2*pi]"},
      {"1,7,508,0,1,0.5,0.1,1,1.5,480,1,3.2\n", "line 2", "theta_emc_rad", "outside [0, pi]"},
      {"1,7,508,0,1,0.5,0.1,1,1.5,-1,1,1.5\n", "line 2", "energy_mev", "negative"},
      {"1,7,0,0,1,0.5,0.1,1,1.5,480,1,1.5\n", "line 2", "beam_energy_mev", "0 MeV is not a beam energy"},
      {"1,7,-5,0,1,0.5,0.1,1,1.5,480,1,1.5\n", "line 2", "beam_energy_mev", "-5 MeV is not a beam energy"},
      {"1,7,0.6125,0,1,0.5,0.1,1,1.5,480,1,1.5\n", "line 2", "beam_energy_mev", "GeV?"},
      {"1,7,612500,0,1,0.5,0.1,1,1.5,480,1,1.5\n", "line 2", "beam_energy_mev", "keV?"},
      {"1,7,,0,1,0.5,0.1,1,1.5,480,1,1.5\n", "line 2", "beam_energy_mev", "empty"},
      {"1,7,508,0,1,0.5,,1,1.5,480,1,1.5\n", "line 2", "rho_cm", "complete track"},
      {"1,7,508,0,1,0.5,0.1,1,,,,\n", "line 2", "theta_ts_rad", "complete track"},
      {"1,7,508,0,1,0.5,0.1,1,1.5,480,,1.5\n", "line 2", "phi_emc_rad", "cluster"},
      {"1,7,508,0,0,,,,,,1,\n", "line 2", "energy_mev", "cluster"},
      {"1,8,508,0,0,0.5,,,,200,3,2\n", "line 2", "z0_cm", "photon"},
      {"1,8,508,0,0,,,,1.5,200,3,2\n", "line 2", "theta_ts_rad", "photon"},
      {"1,8,508,0,0,,,,,,,\n", "line 2", "energy_mev", "needs an EMC cluster"},
      // the rows of an event share beam energy and veto
      {"1,7,508,0,1,0.5,0.1,1,1.5,480,1,1.5\n1,7,509,0,0,,,,,200,3,2\n", "line 3", "beam_energy_mev", "differs"},
      {"1,7,508,0,1,0.5,0.1,1,1.5,480,1,1.5\n1,7,508,1,0,,,,,200,3,2\n", "line 3", "muon_veto", "differs"},
      // comment and blank lines count as lines
      {"# note\n\n1,7,508,0,1,0.5,0.1,1,1.5,480,1,abc\n", "line 4", "theta_emc_rad", "not a finite"},
  };
  for (const CsvCase& c : cases) {
    SCOPED_TRACE(c.body);
    const std::string message = csvError(kHeader + c.body);
    EXPECT_THAT(message, HasSubstr("bad.csv"));
    EXPECT_THAT(message, HasSubstr(std::string(c.where) + ":"));
    EXPECT_THAT(message, HasSubstr(c.column));
    EXPECT_THAT(message, HasSubstr(c.reason));
  }
}

TEST_F(EventFile, CsvInconsistentEventIsFoundAcrossBlocks) {
  // blockRows = 4 in csvError: the event of lines 2–7 spans the first block boundary.
  std::string body;
  for (int i = 0; i < 5; ++i) body += "1,7,508,0,0,,,,,200,3,2\n";
  body += "1,7,508,1,0,,,,,200,3,2\n";
  const std::string message = csvError(kHeader + body);
  EXPECT_THAT(message, HasSubstr("line 7: column 'muon_veto'"));
}

TEST_F(EventFile, CsvWrongFieldCountAndTruncatedLastLine) {
  std::string message = csvError(kHeader + kGoodCharged + "1,7,508\n");
  EXPECT_THAT(message, HasSubstr("bad.csv: line 3: expected 12 fields, got 3"));
  message = csvError(kHeader + kGoodCharged + "1,7,508,0,1,0.5,0.1,1,1.5,480,1,1.5,9\n");
  EXPECT_THAT(message, HasSubstr("line 3: expected 12 fields, got 13"));
  // A file cut in the middle of a row.
  message = csvError(kHeader + kGoodCharged + "1,7,508,0,1,0.");
  EXPECT_THAT(message, HasSubstr("bad.csv: line 3:"));
  EXPECT_THAT(message, HasSubstr("truncated"));
  message = csvError(kHeader + kGoodCharged + "1,7,508,0,1,0.5,0.1,1,1.5,480,1,");
  EXPECT_THAT(message, HasSubstr("line 3:"));
  EXPECT_THAT(message, HasSubstr("truncated"));
  // Cut inside the last field: every field count is right and "1.4" is a number, so only the
  // missing newline tells (issue 9: this was read as a valid, truncated value).
  message = csvError(kHeader + kGoodCharged + "1,8,508,0,1,0.5,0.1,1,1.5,480,1.01,1.4");
  EXPECT_THAT(message, HasSubstr("bad.csv: line 3: the file ends inside this row"));
  EXPECT_THAT(message, HasSubstr("truncated"));
}

TEST_F(EventFile, CsvHeaderErrors) {
  const std::string good = kCsvHeader;
  struct HeaderCase {
    std::string text;
    const char* mention;
  };
  const HeaderCase cases[] = {
      {good.substr(0, good.rfind(',')) + "\n", "missing column(s) 'theta_emc_rad'"},
      {good + ",extra\n", "unexpected or repeated column(s) 'extra'"},
      {"run,event,beam_energy_mev,muon_veto,charged,z0_cm,rho_cm,phi_ts,theta_ts_rad,energy_mev,"
       "phi_emc_rad,"
       "theta_emc_rad\n",
       "'phi_ts_rad' is missing and 'phi_ts' is unexpected"},
      {"run,event,beam_energy_mev,muon_veto,charged,rho_cm,z0_cm,phi_ts_rad,theta_ts_rad,energy_"
       "mev,phi_emc_rad,"
       "theta_emc_rad\n",
       "column 6 is 'rho_cm', expected 'z0_cm'"},
      {good + ",run\n", "repeated"},
      {"1,7,508,0,1,0.5,0.1,1,1.5,480,1.01,1.49\n", "header"},
  };
  for (const HeaderCase& c : cases) {
    SCOPED_TRACE(c.text);
    const std::string message = csvError(c.text + kGoodCharged);
    EXPECT_THAT(message, HasSubstr("bad.csv: line 1: header:"));
    EXPECT_THAT(message, HasSubstr(c.mention));
  }
  EXPECT_THAT(csvError("# generator: x\n" + good.substr(1) + "\n"), HasSubstr("bad.csv: line 2: header:"));
  for (const std::string& text : {std::string(), std::string("# only a comment\n\n")}) {
    const std::string message = csvError(text);
    EXPECT_THAT(message, HasSubstr("bad.csv"));
    EXPECT_THAT(message, HasSubstr("header"));
  }
  EXPECT_THAT(csvError("# k: 1\n# k: 2\n" + kHeader), HasSubstr("line 2: attribute 'k' given twice"));
}

// -------------------------------------------------------------------------- HDF5 errors

// A raw /events (and optional /truth) file written with the C API, for malformed inputs.
struct RawColumn {
  std::string name;
  hid_t type;
  std::vector<double> values;  // converted by HDF5 to `type`
};

std::vector<RawColumn> rawColumns(const std::vector<ParticleRow>& rows) {
  const auto column = [&](const char* name, hid_t type, auto get) {
    RawColumn c{name, type, {}};
    for (const auto& r : rows) c.values.push_back(static_cast<double>(get(r)));
    return c;
  };
  return {column("run", H5T_STD_I32LE, [](const ParticleRow& r) { return r.run; }),
          column("event", H5T_STD_I64LE, [](const ParticleRow& r) { return r.event; }),
          column("beam_energy_mev", H5T_IEEE_F64LE, [](const ParticleRow& r) { return r.beamEnergy; }),
          column("muon_veto", H5T_STD_I8LE, [](const ParticleRow& r) { return r.muonVeto; }),
          column("charged", H5T_STD_I8LE, [](const ParticleRow& r) { return r.charged; }),
          column("z0_cm", H5T_IEEE_F64LE, [](const ParticleRow& r) { return r.z0; }),
          column("rho_cm", H5T_IEEE_F64LE, [](const ParticleRow& r) { return r.rho; }),
          column("phi_ts_rad", H5T_IEEE_F64LE, [](const ParticleRow& r) { return r.phiTs; }),
          column("theta_ts_rad", H5T_IEEE_F64LE, [](const ParticleRow& r) { return r.thetaTs; }),
          column("energy_mev", H5T_IEEE_F64LE, [](const ParticleRow& r) { return r.energy; }),
          column("phi_emc_rad", H5T_IEEE_F64LE, [](const ParticleRow& r) { return r.phiEmc; }),
          column("theta_emc_rad", H5T_IEEE_F64LE, [](const ParticleRow& r) { return r.thetaEmc; })};
}

void writeRawHdf5(const std::string& path, const std::vector<RawColumn>& events,
                  const std::vector<RawColumn>& truth = {}, const char* eventsGroup = "events") {
  const hid_t file = H5Fcreate(path.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
  ASSERT_GE(file, 0);
  const auto group = [&](const char* name, const std::vector<RawColumn>& columns) {
    if (columns.empty()) return;
    const hid_t g = H5Gcreate2(file, name, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
    ASSERT_GE(g, 0);
    for (const RawColumn& c : columns) {
      const hsize_t n = c.values.size();
      const hid_t space = H5Screate_simple(1, &n, nullptr);
      const hid_t ds = H5Dcreate2(g, c.name.c_str(), c.type, space, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
      ASSERT_GE(ds, 0) << c.name;
      if (n > 0) {
        ASSERT_GE(H5Dwrite(ds, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, c.values.data()), 0);
      }
      H5Dclose(ds);
      H5Sclose(space);
    }
    H5Gclose(g);
  };
  group(eventsGroup, events);
  group("truth", truth);
  H5Fclose(file);
}

RawColumn& columnNamed(std::vector<RawColumn>& columns, const std::string& name) {
  for (auto& c : columns) {
    if (c.name == name) return c;
  }
  throw std::runtime_error("no column " + name);
}

TEST_F(EventFile, Hdf5RawFileWithoutChunkingReads) {
  const auto rows = sampleRows(4);
  writeRawHdf5(path("raw.h5"), rawColumns(rows));
  auto back = readAll({path("raw.h5")});
  ASSERT_TRUE(back.ok()) << back.error().message;
  expectSameRows(back->rows, rows);
}

TEST_F(EventFile, Hdf5ValueErrorsNameFileRecordAndColumn) {
  struct Hdf5Case {
    const char* column;
    std::size_t record;
    double value;
    const char* reason;
  };
  // sampleRows(4): records 0,1 event 0; 2,3,4 event 1 (4 is a photon); 5..8 event 2.
  const Hdf5Case cases[] = {
      {"beam_energy_mev", 2, kNaN, "empty"},
      {"beam_energy_mev", 0, 0.0, "0 MeV is not a beam energy"},
      {"beam_energy_mev", 3, 600.0, "differs"},
      {"muon_veto", 1, 2.0, "must be 0 or 1"},
      {"muon_veto", 1, 1.0, "differs"},
      {"charged", 0, -1.0, "must be 0 or 1"},
      {"phi_emc_rad", 1, 7.0, "outside [0, 2*pi]"},
      {"theta_ts_rad", 0, 4.0, "outside [0, pi]"},
      {"rho_cm", 0, kNaN, "complete track"},
      {"rho_cm", 1, std::numeric_limits<double>::infinity(), "not a finite number"},
      {"z0_cm", 4, 1.0, "photon"},
      {"theta_emc_rad", 0, kNaN, "cluster"},
      {"energy_mev", 4, kNaN, "cluster fields"},
      {"energy_mev", 0, -3.0, "negative"},
  };
  for (const Hdf5Case& c : cases) {
    SCOPED_TRACE(fmt::format("{} = {} at {}", c.column, c.value, c.record));
    auto columns = rawColumns(sampleRows(4));
    columnNamed(columns, c.column).values.at(c.record) = c.value;
    writeRawHdf5(path("bad.h5"), columns);
    auto r = readAll({path("bad.h5")}, 2);
    ASSERT_FALSE(r.ok());
    EXPECT_THAT(r.error().message, HasSubstr(fmt::format("bad.h5: record {}: column '{}'", c.record, c.column)));
    EXPECT_THAT(r.error().message, HasSubstr(c.reason));
  }
}

TEST_F(EventFile, Hdf5StructureErrors) {
  const auto rows = sampleRows(3);
  const auto expectError = [&](const std::vector<RawColumn>& events, const std::vector<RawColumn>& truth,
                               std::vector<std::string> mentions, const char* group = "events") {
    writeRawHdf5(path("bad.h5"), events, truth, group);
    auto r = readAll({path("bad.h5")});
    ASSERT_FALSE(r.ok());
    mentions.push_back("bad.h5");
    for (const auto& m : mentions) EXPECT_THAT(r.error().message, HasSubstr(m));
  };
  {
    SCOPED_TRACE("missing dataset");
    auto columns = rawColumns(rows);
    columns.pop_back();
    expectError(columns, {}, {"missing dataset '/events/theta_emc_rad'"});
  }
  {
    SCOPED_TRACE("unequal lengths");
    auto columns = rawColumns(rows);
    columnNamed(columns, "energy_mev").values.pop_back();
    expectError(columns, {}, {"energy_mev", "unequal length"});
  }
  {
    SCOPED_TRACE("wrong type");
    auto columns = rawColumns(rows);
    columnNamed(columns, "run").type = H5T_IEEE_F64LE;
    expectError(columns, {}, {"'/events/run'", "type is 64-bit float, expected 32-bit signed integer"});
    columns = rawColumns(rows);
    columnNamed(columns, "phi_ts_rad").type = H5T_IEEE_F32LE;
    expectError(columns, {}, {"'/events/phi_ts_rad'", "32-bit float"});
    columns = rawColumns(rows);
    columnNamed(columns, "charged").type = H5T_STD_U8LE;
    expectError(columns, {}, {"'/events/charged'", "unsigned"});
  }
  {
    SCOPED_TRACE("extra dataset");
    auto columns = rawColumns(rows);
    columns.push_back({"extra", H5T_IEEE_F64LE, std::vector<double>(rows.size(), 1.0)});
    expectError(columns, {}, {"unexpected dataset '/events/extra'"});
  }
  {
    SCOPED_TRACE("no /events");
    expectError(rawColumns(rows), {}, {"missing group '/events'"}, "particles");
  }
  {
    SCOPED_TRACE("truth of another length");
    std::vector<RawColumn> truth = {{"pdg", H5T_STD_I32LE, std::vector<double>(rows.size() + 1, 11.0)}};
    for (const char* n : {"energy_mev", "theta_rad", "phi_rad", "vertex_x_cm", "vertex_y_cm", "vertex_z_cm",
                          "shower_x_cm", "shower_y_cm", "shower_z_cm"}) {
      truth.push_back({n, H5T_IEEE_F64LE, std::vector<double>(rows.size() + 1, 1.0)});
    }
    expectError(rawColumns(rows), truth, {"'/truth'", "records"});
    truth.pop_back();
    for (auto& t : truth) t.values.resize(rows.size());
    expectError(rawColumns(rows), truth, {"missing dataset '/truth/shower_z_cm'"});
  }
}

TEST_F(EventFile, Hdf5TruncatedFileFails) {
  const auto rows = sampleRows(8000);
  ASSERT_TRUE(writeFile(path("full.h5"), rows, {true, kAttributes}, sampleTruth(rows.size())).ok());
  const std::string bytes = readBytes(path("full.h5"));
  for (const double fraction : {0.5, 0.9, 0.999}) {
    SCOPED_TRACE(fraction);
    writeBytes(path("cut.h5"), bytes.substr(0, static_cast<std::size_t>(fraction * static_cast<double>(bytes.size()))));
    auto r = readAll({path("cut.h5")});
    ASSERT_FALSE(r.ok());
    EXPECT_THAT(r.error().message, HasSubstr("cut.h5"));
  }
}

TEST_F(EventFile, MissingAndNonHdf5FilesFail) {
  auto r = EventReader::open({path("nothing.h5")});
  ASSERT_FALSE(r.ok());
  EXPECT_THAT(r.error().message, HasSubstr("nothing.h5: no such file"));

  r = EventReader::open({path("nothing.csv")});
  ASSERT_FALSE(r.ok());
  EXPECT_THAT(r.error().message, HasSubstr("nothing.csv: no such file"));

  writeBytes(path("text.h5"), "hello\n");
  r = EventReader::open({path("text.h5")});
  ASSERT_FALSE(r.ok());
  EXPECT_THAT(r.error().message, HasSubstr("text.h5: not an HDF5 file"));
  // A CSV event file under another name is named as one.
  writeBytes(path("events.txt"), std::string(kCsvHeader) + "\n");
  r = EventReader::open({path("events.txt")});
  ASSERT_FALSE(r.ok());
  EXPECT_THAT(r.error().message, HasSubstr("events.txt: this is a CSV event file: name it *.csv"));

  // A missing second file is found before the first is read.
  ASSERT_TRUE(writeFile(path("good.csv"), sampleRows(2)).ok());
  r = EventReader::open({path("good.csv"), path("later.h5")});
  ASSERT_FALSE(r.ok());
  EXPECT_THAT(r.error().message, HasSubstr("later.h5: no such file"));

  EXPECT_FALSE(EventReader::open({}).ok());
  EXPECT_FALSE(EventReader::open({path("good.csv")}, ReaderOptions{0}).ok());
}

// Another of emcalign's files given as events is named by what it is, never by the raw
// bytes or the columns it lacks.
TEST_F(EventFile, FilesOfAnotherKindAreNamed) {
  const auto message = [&](const std::string& name, const std::string& content) {
    writeBytes(path(name), content);
    auto r = EventReader::open({path(name)});
    return r.ok() ? std::string("opened") : r.error().message;
  };
  EXPECT_THAT(message("truth.json", R"({"format": "emcalign-alignment/1", "parameters": {"alpha": 1}})"),
              HasSubstr("truth.json: this is a parameter file (its format: emcalign-alignment/1), not an event file"));
  EXPECT_THAT(message("result.json", R"({"format": "emcalign-alignment/1", "errors": {}})"),
              HasSubstr("this is a fit result (its format: emcalign-alignment/1), not an event file"));
  EXPECT_THAT(message("c.db", std::string("SQLite format 3\0", 16) + std::string(100, '\0')),
              HasSubstr("c.db: this is an SQLite database (a conditions database?), not an event file"));
  const std::string exported =
      "# emcalign conditions export: tag t of sqlite:c.db\n# units: alpha=deg\n"
      "first_run,last_run,payload,inserted,status,chi2,ndf,chi2_statistical_errors,sigma_sys_method,sigma_sys_deg,"
      "selected_events,alpha,alpha_error\n1,4,abc,DATE,converged,1,1,1,paper,10,2.8,0.1\n";
  const std::string conditions = message("T.csv", exported);
  EXPECT_THAT(conditions,
              HasSubstr("T.csv: this is a conditions export (emcalign conditions export), not an event file"));
  // Its comment lines gone, it is still known by its header.
  EXPECT_THAT(message("T2.csv", exported.substr(exported.find("first_run"))), HasSubstr("this is a conditions export"));
  EXPECT_THAT(message("prof.csv", "i_phi,i_theta,n,phi_mean_rad\n"), HasSubstr("this is a profile CSV"));
  // A header with nothing in common: what it has, briefly, not 50 columns.
  std::string wide = "a0";
  for (int k = 1; k < 50; ++k) wide += fmt::format(",a{}", k);
  const std::string other = message("other.csv", wide + "\n");
  EXPECT_THAT(other, HasSubstr("other.csv: line 1: header: none of an event file's columns"));
  EXPECT_THAT(other, HasSubstr("'a5', … (50 in all)"));
  EXPECT_THAT(other, Not(HasSubstr("'a6'")));
  EXPECT_LT(other.size(), 250U) << other;
}

TEST_F(EventFile, ReaderErrorIsSticky) {
  writeBytes(path("bad.csv"), kHeader + kGoodCharged + "1,8,508,0,1,oops,0.1,1,1.5,480,1,1.5\n" + kGoodCharged);
  auto reader = EventReader::open({path("bad.csv")}, ReaderOptions{1});
  ASSERT_TRUE(reader.ok());
  std::vector<ParticleRow> block;
  auto more = (*reader)->next(block);
  ASSERT_FALSE(more.ok());
  EXPECT_THAT(more.error().message, HasSubstr("line 3: column 'z0_cm'"));
  more = (*reader)->next(block);
  ASSERT_FALSE(more.ok());
  EXPECT_TRUE(block.empty());
}

}  // namespace
}  // namespace emcalign::io

// ------------------------------------------------------------- repeated and absurd events

namespace emcalign::io {
namespace {

TEST(EventFileFormat, DashIsCsv) { EXPECT_EQ(formatOf("-"), EventFormat::Csv); }

TEST_F(EventFile, TheSameFileTwiceIsRefused) {
  ASSERT_TRUE(writeFile(path("a.csv"), sampleRows(3)).ok());
  fs::create_symlink(path("a.csv"), path("b.csv"));
  auto r = readAll({path("a.csv"), path("b.csv")});
  ASSERT_FALSE(r.ok());
  EXPECT_THAT(r.error().message, HasSubstr("b.csv: is the same file as " + path("a.csv")));
}

TEST_F(EventFile, RepeatedEventsAreRefusedNamingBothPlaces) {
  for (const char* ext : {".csv", ".h5"}) {
    SCOPED_TRACE(ext);
    const auto rows = sampleRows(5);
    ASSERT_TRUE(writeFile(path(std::string("a") + ext), rows).ok());
    ASSERT_TRUE(writeFile(path(std::string("copy") + ext), rows).ok());
    auto r = readAll({path(std::string("a") + ext), path(std::string("copy") + ext)}, 3);
    ASSERT_FALSE(r.ok()) << "a copy of a file counted twice";
    const std::string first = std::string(ext) == ".csv" ? "a.csv: line 2" : "a.h5: record 0";
    const std::string again = std::string(ext) == ".csv" ? "copy.csv: line 2" : "copy.h5: record 0";
    EXPECT_THAT(r.error().message, HasSubstr(again + ": run 1 event 0 appears again"));
    EXPECT_THAT(r.error().message, HasSubstr("its rows start at " + path("") + first));
  }
}

TEST_F(EventFile, RowsOfAnEventApartAreRefused) {
  // Event 7's rows are split by event 8: the selection would see two broken events.
  const std::string text =
      kHeader + "1,7,508,0,0,,,,,200,3.0,2.0\n" + "1,8,508,0,0,,,,,200,3.0,2.0\n" + "1,7,508,0,0,,,,,210,3.1,2.1\n";
  const std::string message = csvError(text);
  EXPECT_THAT(message, HasSubstr("bad.csv: line 4: run 1 event 7 appears again (its rows start at "));
  EXPECT_THAT(message, HasSubstr("bad.csv: line 2)"));
  EXPECT_THAT(message, HasSubstr("contiguous"));
}

// The check keeps intervals of consecutive event numbers (event_file.cpp, SeenEvents): a
// repeat inside an interval, after a gap, in another run, and after the events come in no
// order (more than 64 sequences), is still found; an event in an earlier gap is not a repeat.
TEST_F(EventFile, RepeatsAreFoundInsideIntervalsOfConsecutiveEvents) {
  const auto row = [](int run, int event) { return fmt::format("{},{},508,0,0,,,,,200,3.0,2.0\n", run, event); };
  std::string ok = kHeader;
  for (int e : {1, 2, 3, 5, 6}) ok += row(1, e);
  ok += row(2, 1) + row(2, 2) + row(1, 4);  // run 2, then run 1's gap: new, not repeats
  writeBytes(path("ok.csv"), ok);
  EXPECT_TRUE(readAll({path("ok.csv")}).ok());
  EXPECT_THAT(csvError(ok + row(1, 2)), HasSubstr("line 10: run 1 event 2 appears again (its rows start at "));
  EXPECT_THAT(csvError(ok + row(1, 5)), HasSubstr("line 10: run 1 event 5 appears again"));
  EXPECT_THAT(csvError(ok + row(2, 2)), HasSubstr("line 10: run 2 event 2 appears again"));
  // 100 decreasing events, each its own sequence: past 64 the check turns to fingerprints,
  // which still hold every event of the intervals before.
  std::string shuffled = kHeader;
  for (int e = 1000; e < 1010; ++e) shuffled += row(3, e);
  for (int e = 100; e > 0; --e) shuffled += row(4, e);
  writeBytes(path("shuffled.csv"), shuffled);
  EXPECT_TRUE(readAll({path("shuffled.csv")}).ok());
  EXPECT_THAT(csvError(shuffled + row(3, 1005)), HasSubstr("line 112: run 3 event 1005 appears again"));
}

TEST_F(EventFile, AnEventOfMoreThanAThousandRowsIsRefused) {
  std::string text = kHeader;
  for (int i = 0; i < 1001; ++i) text += "1,7,508,0,0,,,,,200,3.0,2.0\n";
  EXPECT_THAT(csvError(text), HasSubstr("bad.csv: line 1002: run 1 event 7 has more than 1000 rows"));
  std::string thousand = kHeader;
  for (int i = 0; i < 1000; ++i) thousand += "1,7,508,0,0,,,,,200,3.0,2.0\n";
  writeBytes(path("ok.csv"), thousand);
  EXPECT_TRUE(readAll({path("ok.csv")}).ok());
}

// A billion records that are all one event, stored as fill values (the file is a few kB):
// once this was read into one block until memory ran out.
TEST_F(EventFile, Hdf5BillionRowEventIsRefusedAtOnce) {
  const hsize_t n = 1'000'000'000, chunk = 1 << 16;
  const hid_t file = H5Fcreate(path("huge.h5").c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
  ASSERT_GE(file, 0);
  const hid_t group = H5Gcreate2(file, "events", H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
  const double nan = kNaN;
  for (const RawColumn& c : rawColumns({photonRow(1, 7, 508, 200, 3.0, 2.0)})) {
    const hid_t space = H5Screate_simple(1, &n, nullptr);
    const hid_t dcpl = H5Pcreate(H5P_DATASET_CREATE);
    H5Pset_chunk(dcpl, 1, &chunk);
    const double value = c.values[0];
    H5Pset_fill_value(dcpl, H5T_NATIVE_DOUBLE, std::isnan(value) ? &nan : &value);
    const hid_t ds = H5Dcreate2(group, c.name.c_str(), c.type, space, H5P_DEFAULT, dcpl, H5P_DEFAULT);
    ASSERT_GE(ds, 0) << c.name;
    H5Dclose(ds);
    H5Pclose(dcpl);
    H5Sclose(space);
  }
  H5Gclose(group);
  H5Fclose(file);
  EXPECT_LT(fs::file_size(path("huge.h5")), 100'000u);
  auto r = readAll({path("huge.h5")});
  ASSERT_FALSE(r.ok());
  EXPECT_THAT(r.error().message, HasSubstr("huge.h5: record 1000: run 1 event 7 has more than 1000 rows"));
}

}  // namespace
}  // namespace emcalign::io

// ------------------------------------------------- files that crash or hang libhdf5 itself

namespace emcalign::io {
namespace {

// Found by fuzzing (tests/fuzz/regressions/): inside libhdf5 1.10 they end in SIGFPE, an
// endless loop and an exabyte allocation. The reader runs HDF5 in a child process, so each
// becomes an error naming the file.
std::string regression(const char* name) {
  return std::string(EMCALIGN_SOURCE_DIR) + "/tests/fuzz/regressions/" + name;
}

TEST(EventFileIsolation, ACrashOfTheHdf5LibraryIsAnError) {
  auto r = readAll({regression("hdf5-chunk-dimension-zero.h5")});
  ASSERT_FALSE(r.ok());
  EXPECT_THAT(r.error().message, HasSubstr("hdf5-chunk-dimension-zero.h5: the HDF5 library crashed reading this file"));
  EXPECT_THAT(r.error().message, HasSubstr("signal 8"));
}

TEST(EventFileIsolation, AnHdf5LibraryThatLoopsIsStoppedAfterTheTimeout) {
  ReaderOptions o;
  o.hdf5TimeoutSeconds = 1.0;
  const auto start = std::chrono::steady_clock::now();
  auto reader = EventReader::open({regression("hdf5-global-heap-loop.h5")}, o);
  ASSERT_FALSE(reader.ok());
  EXPECT_THAT(reader.error().message, HasSubstr("did not answer within 1 s"));
  EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(), 10.0);
}

TEST(EventFileIsolation, AHugeAllocationIsAnError) {
  auto r = readAll({regression("hdf5-huge-allocation.h5")});
  ASSERT_FALSE(r.ok());
  EXPECT_THAT(r.error().message, HasSubstr("hdf5-huge-allocation.h5"));
}

TEST(EventFileIsolation, AttributesAndTruthCrossTheProcessBoundaryExactly) {
  const auto rows = sampleRows(3000);  // more than one message of rows
  const auto truth = sampleTruth(rows.size());
  const auto dir = fs::temp_directory_path() / fmt::format("emcalign-isolation-{}", ::getpid());
  fs::create_directories(dir);
  const std::string file = (dir / "e.h5").string();
  ASSERT_TRUE(writeFile(file, rows, {true, kAttributes}, truth).ok());
  auto back = readAll({file}, 1000);
  fs::remove_all(dir);
  ASSERT_TRUE(back.ok()) << back.error().message;
  expectSameRows(back->rows, rows);
  expectSameTruth(back->truth, truth);
  EXPECT_EQ(back->attributes, kAttributes);
}

}  // namespace
}  // namespace emcalign::io

// -------------------------------------------------------------------------------- hits

namespace emcalign::io {
namespace {

// Rows of sampleRows() with hits on their clusters: 1 + (i % 4) counters each.
std::vector<Hit> attachHits(std::vector<ParticleRow>& rows) {
  std::vector<Hit> hits;
  for (std::size_t i = 0; i < rows.size(); ++i) {
    rows[i].hitCount = std::isnan(rows[i].energy) ? 0 : 1 + static_cast<int>(i % 4);
    for (int k = 0; k < rows[i].hitCount; ++k) {
      hits.push_back({static_cast<std::int32_t>(100 * k + i % 1632), 1.0 / 3.0 + static_cast<double>(i) + k});
    }
  }
  return hits;
}

Result<std::vector<Hit>> readHits(const std::vector<std::string>& paths, std::size_t blockRows,
                                  std::vector<ParticleRow>* rowsOut = nullptr) {
  auto reader = EventReader::open(paths, ReaderOptions{blockRows});
  if (!reader) return reader.error();
  std::vector<Hit> all;
  std::vector<ParticleRow> rows;
  while (true) {
    auto more = (*reader)->next(rows);
    if (!more) return more.error();
    if (!*more) break;
    const auto* hits = (*reader)->hits();
    if (hits == nullptr) return Error{"no hits"};
    std::size_t sum = 0;
    for (const auto& r : rows) sum += static_cast<std::size_t>(r.hitCount);
    EXPECT_EQ(sum, hits->size()) << "a block's hits are its rows'";
    all.insert(all.end(), hits->begin(), hits->end());
    if (rowsOut) rowsOut->insert(rowsOut->end(), rows.begin(), rows.end());
  }
  return all;
}

TEST_F(EventFile, HitsRoundTripThroughHdf5InAnyBlocks) {
  auto rows = sampleRows(3000);
  const auto hits = attachHits(rows);
  WriterOptions o{true, kAttributes};
  o.withHits = true;
  ASSERT_TRUE(writeFile(path("h.h5"), rows, o, sampleTruth(rows.size()), hits).ok());
  for (std::size_t block : {std::size_t{1}, std::size_t{7}, std::size_t{65536}}) {
    std::vector<ParticleRow> back;
    auto got = readHits({path("h.h5")}, block, &back);
    ASSERT_TRUE(got.ok()) << got.error().message;
    ASSERT_EQ(got->size(), hits.size());
    for (std::size_t k = 0; k < hits.size(); ++k) {
      ASSERT_EQ((*got)[k].counter, hits[k].counter);
      ASSERT_TRUE(sameDouble((*got)[k].energy, hits[k].energy));
    }
    for (std::size_t i = 0; i < rows.size(); ++i) ASSERT_EQ(back[i].hitCount, rows[i].hitCount);
  }
  // CSV has no hits: written without them, read as none.
  ASSERT_TRUE(writeFile(path("h.csv"), rows, o, {}, hits).ok());
  auto reader = EventReader::open({path("h.csv")});
  ASSERT_TRUE(reader.ok());
  std::vector<ParticleRow> block;
  ASSERT_TRUE(*(*reader)->next(block));
  EXPECT_EQ((*reader)->hits(), nullptr);
  EXPECT_EQ(block[0].hitCount, 0);
}

// A reader that asks for neither (the fit's selection and profiles) reads /events only:
// the same rows, no truth, no hits, and a broken /truth does not concern it.
TEST_F(EventFile, ReadingWithoutTruthAndHitsGivesTheSameRows) {
  auto rows = sampleRows(3000);
  const auto hits = attachHits(rows);
  WriterOptions o{true, kAttributes};
  o.withHits = true;
  ASSERT_TRUE(writeFile(path("h.h5"), rows, o, sampleTruth(rows.size()), hits).ok());
  const ReaderOptions rowsOnly{.truth = false, .hits = false};
  auto reader = EventReader::open({path("h.h5")}, rowsOnly);
  ASSERT_TRUE(reader.ok()) << reader.error().message;
  std::vector<ParticleRow> block, back;
  while (true) {
    auto more = (*reader)->next(block);
    ASSERT_TRUE(more.ok()) << more.error().message;
    if (!*more) break;
    EXPECT_EQ((*reader)->truth(), nullptr);
    EXPECT_EQ((*reader)->hits(), nullptr);
    back.insert(back.end(), block.begin(), block.end());
  }
  ASSERT_EQ(back.size(), rows.size());
  for (std::size_t i = 0; i < rows.size(); ++i) {
    ASSERT_EQ(back[i].event, rows[i].event);
    ASSERT_TRUE(sameDouble(back[i].thetaEmc, rows[i].thetaEmc)) << i;
    ASSERT_EQ(back[i].hitCount, 0) << "hits not read";
  }
  // /truth cut short: an error for a reader of the truth, nothing for one of the rows.
  const hid_t f = H5Fopen(path("h.h5").c_str(), H5F_ACC_RDWR, H5P_DEFAULT);
  ASSERT_GE(f, 0);
  ASSERT_GE(H5Ldelete(f, "/truth/pdg", H5P_DEFAULT), 0);
  H5Fclose(f);
  EXPECT_THAT(readAll({path("h.h5")}).error().message, HasSubstr("missing dataset '/truth/pdg'"));
  auto again = EventReader::open({path("h.h5")}, rowsOnly);
  ASSERT_TRUE(again.ok()) << again.error().message;
  EXPECT_TRUE((*again)->next(block).ok());
}

TEST_F(EventFile, WriterRefusesHitsThatDoNotMatchTheRows) {
  auto rows = sampleRows(4);
  auto hits = attachHits(rows);
  WriterOptions o;
  o.withHits = true;
  auto w = EventWriter::open(path("h.h5"), o);
  ASSERT_TRUE(w.ok());
  hits.pop_back();
  EXPECT_THAT((*w)->append(rows, {}, hits).error().message, HasSubstr("more hits than the"));
  auto noCluster = sampleRows(4);
  const auto hits2 = attachHits(noCluster);
  noCluster[8].hitCount = 2;  // row 8 has no cluster (sampleRows: the fourth row of event 2)
  auto w2 = EventWriter::open(path("h2.h5"), o);
  ASSERT_TRUE(std::isnan(noCluster[8].energy));
  EXPECT_THAT((*w2)->append(noCluster, {}, hits2).error().message, HasSubstr("row 8"));
}

// Broken hit columns, written with the C API: each is refused naming the record.
TEST_F(EventFile, Hdf5HitsAreCheckedForConsistency) {
  auto rows = sampleRows(4);
  const auto hits = attachHits(rows);
  const auto write = [&](const std::string& file, std::vector<std::int64_t> offset, std::vector<std::int32_t> count,
                         std::vector<std::int32_t> counter) {
    writeRawHdf5(file, rawColumns(rows));
    const hid_t f = H5Fopen(file.c_str(), H5F_ACC_RDWR, H5P_DEFAULT);
    const hid_t events = H5Gopen2(f, "events", H5P_DEFAULT);
    const hid_t g = H5Gcreate2(f, "hits", H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
    const auto put = [](hid_t group, const char* name, hid_t type, hid_t memType, const void* data, hsize_t n) {
      const hid_t space = H5Screate_simple(1, &n, nullptr);
      const hid_t ds = H5Dcreate2(group, name, type, space, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
      H5Dwrite(ds, memType, H5S_ALL, H5S_ALL, H5P_DEFAULT, data);
      H5Dclose(ds);
      H5Sclose(space);
    };
    std::vector<double> energy(counter.size(), 5.0);
    put(events, "hit_offset", H5T_STD_I64LE, H5T_NATIVE_INT64, offset.data(), offset.size());
    put(events, "hit_count", H5T_STD_I32LE, H5T_NATIVE_INT32, count.data(), count.size());
    put(g, "counter", H5T_STD_I32LE, H5T_NATIVE_INT32, counter.data(), counter.size());
    put(g, "energy_mev", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, energy.data(), energy.size());
    H5Gclose(g);
    H5Gclose(events);
    H5Fclose(f);
  };
  std::vector<std::int64_t> offset;
  std::vector<std::int32_t> count;
  std::int64_t at = 0;
  for (const auto& r : rows) {
    offset.push_back(at);
    count.push_back(r.hitCount);
    at += r.hitCount;
  }
  std::vector<std::int32_t> counter(static_cast<std::size_t>(at), 7);
  write(path("good.h5"), offset, count, counter);
  auto good = readHits({path("good.h5")}, 3);
  ASSERT_TRUE(good.ok()) << good.error().message;
  EXPECT_EQ(good->size(), hits.size());

  auto hole = offset;
  hole[3] += 1;
  write(path("hole.h5"), hole, count, counter);
  EXPECT_THAT(readHits({path("hole.h5")}, 3).error().message, HasSubstr("record 3: column 'hit_offset'"));
  auto tooMany = count;
  tooMany[2] = 5000;
  write(path("many.h5"), offset, tooMany, counter);
  EXPECT_THAT(readHits({path("many.h5")}, 3).error().message, HasSubstr("record 2: column 'hit_count'"));
  auto extra = counter;
  extra.push_back(1);
  write(path("extra.h5"), offset, count, extra);
  EXPECT_THAT(readHits({path("extra.h5")}, 3).error().message, HasSubstr("the rows use"));
  auto negative = counter;
  negative[4] = -3;
  write(path("negative.h5"), offset, count, negative);
  EXPECT_THAT(readHits({path("negative.h5")}, 3).error().message, HasSubstr("'/hits/counter': -3 is not a counter"));
  // Half the hit columns: refused by name.
  writeRawHdf5(path("half.h5"), rawColumns(rows));
  {
    const hid_t f = H5Fopen(path("half.h5").c_str(), H5F_ACC_RDWR, H5P_DEFAULT);
    const hsize_t n = rows.size();
    const hid_t space = H5Screate_simple(1, &n, nullptr);
    const hid_t ds = H5Dcreate2(f, "/events/hit_count", H5T_STD_I32LE, space, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
    H5Dwrite(ds, H5T_NATIVE_INT32, H5S_ALL, H5S_ALL, H5P_DEFAULT, count.data());
    H5Dclose(ds);
    H5Sclose(space);
    H5Fclose(f);
  }
  EXPECT_THAT(readHits({path("half.h5")}, 3).error().message, HasSubstr("the hits are incomplete"));
}

}  // namespace
}  // namespace emcalign::io
