#include "emcalign/io/file_kind.hpp"

#include <filesystem>
#include <fstream>
#include <string>

#include <gtest/gtest.h>
#include <unistd.h>

namespace emcalign::io {
namespace {

namespace fs = std::filesystem;

TEST(FileKind, ByTheFirstBytes) {
  EXPECT_EQ(describeContent(std::string("\x89HDF\r\n\x1a\n", 8) + "rest"), "an HDF5 file (an event file?)");
  EXPECT_EQ(describeContent(std::string("SQLite format 3\0", 16)), "an SQLite database (a conditions database?)");
  EXPECT_EQ(describeContent("\x89PNG\r\n"), "a PNG image");
  EXPECT_EQ(describeContent("<?xml version=\"1.0\"?>"), "an XML file (GDML placements?)");
  EXPECT_EQ(describeContent("hello\n"), "");
  EXPECT_EQ(describeContent(""), "");
}

TEST(FileKind, CsvFilesByTheirHeader) {
  EXPECT_EQ(describeContent("# note\n\nrun,event,beam_energy_mev,muon_veto\n1,2,3,4\n"), kCsvEventFileKind);
  EXPECT_EQ(describeContent("# truth_parameters: {\"format\": …"), kCsvEventFileKind);
  EXPECT_EQ(describeContent("i_phi,i_theta,n,phi_mean_rad\n"), kProfileCsvKind);
  EXPECT_EQ(describeContent("first_run, last_run, payload, inserted\r\n"),
            "a conditions export (emcalign conditions export)");
  EXPECT_EQ(describeContent("# emcalign conditions export: tag t of sqlite:c.db\n"),
            "a conditions export (emcalign conditions export)");
  EXPECT_EQ(describeContent("index,layer,ring,iphi,hemisphere\n"), "a counters CSV (geometry --counters)");
  EXPECT_EQ(describeContent("x_cm,y_cm,z_cm\n"), "");
}

TEST(FileKind, JsonByItsFormat) {
  EXPECT_EQ(describeContent(R"({"format": "emcalign-alignment/1", "parameters": {}})"),
            "a parameter file (its format: emcalign-alignment/1)");
  EXPECT_EQ(describeContent(R"( {"format": "emcalign-corrections/1"})"),
            "a corrections file (derive-corrections; its format: emcalign-corrections/1)");
  EXPECT_EQ(describeContent(R"({"format": "other/2"})"), "a JSON file (its format: other/2)");
  EXPECT_EQ(describeContent("[1, 2]"), "a JSON file");
  EXPECT_EQ(describeContent("{not json"), "");
  // describeNonJson leaves JSON to its parser.
  EXPECT_EQ(describeNonJson(R"({"format": "emcalign-alignment/1"})"), "");
}

TEST(FileKind, OfAFile) {
  const fs::path dir = fs::temp_directory_path() / ("emcalign_file_kind_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  // A JSON file longer than the first block read is parsed whole.
  std::string big = R"({"format": "emcalign-alignment/1", "pad": ")" + std::string(200'000, 'x') + "\"}";
  std::ofstream(dir / "big.json") << big;
  EXPECT_EQ(describeFileAt((dir / "big.json").string()), "a parameter file (its format: emcalign-alignment/1)");
  EXPECT_EQ(describeFileAt((dir / "missing.h5").string()), "");
  EXPECT_EQ(describeFileAt(dir.string()), "");  // a directory: nothing to say
  fs::remove_all(dir);
}

}  // namespace
}  // namespace emcalign::io
