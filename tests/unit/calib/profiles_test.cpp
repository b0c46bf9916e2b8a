// The profile CSV: written by fit --profile-out, read by fit --profile-in, strictly.

#include "emcalign/calib/profiles.hpp"

#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "emcalign/core/units.hpp"

namespace emcalign::calib {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;
using ::testing::Not;
using units::deg;

// A complete 16 x 10 profile with plausible values, as a fit writes it.
std::vector<ProfileBin> plausibleBins() {
  std::vector<ProfileBin> bins;
  for (int i = 0; i < 16; ++i) {
    for (int j = 0; j < 10; ++j) {
      ProfileBin b;
      b.iPhi = i;
      b.iTheta = j;
      b.n = i == 3 && j == 4 ? 0 : 100 + i + j;
      if (b.n > 0) {
        b.phiMean = (i + 0.3) * 22.5 * deg;
        b.thetaMean = (45.0 + (j + 0.6) * 9.0) * deg;
        b.energyMean = 600.0;
        b.yPhi = 0.01 * std::sin(b.phiMean);
        b.yTheta = -0.002;
        b.sigmaPhi = b.sigmaTheta = 0.004;
      } else {
        b.phiMean = b.thetaMean = b.energyMean = b.yPhi = b.yTheta = b.sigmaPhi = b.sigmaTheta = std::nan("");
      }
      bins.push_back(b);
    }
  }
  markUsedBins(bins, 10);
  return bins;
}

class ProfileCsv : public ::testing::Test {
 protected:
  void SetUp() override {
    file_ = (fs::temp_directory_path() / fmt::format("emcalign_profile_{}_{}.csv", ::getpid(),
                                                     ::testing::UnitTest::GetInstance()->current_test_info()->name()))
                .string();
    text_ = profileCsv(plausibleBins());
  }
  void TearDown() override { fs::remove(file_); }

  // The error of reading the profile with line `line` (1-based, the header is 1) replaced
  // by `f(fields)`.
  template <typename F>
  std::string errorWith(int line, F f) {
    std::vector<std::string> lines;
    std::string l;
    std::istringstream in(text_);
    while (std::getline(in, l)) lines.push_back(l);
    std::vector<std::string> fields;
    std::istringstream ls(lines[static_cast<std::size_t>(line - 1)] + ",");
    while (std::getline(ls, l, ',')) fields.push_back(l);
    f(fields);
    std::string joined;
    for (std::size_t k = 0; k < fields.size(); ++k) joined += (k ? "," : "") + fields[k];
    lines[static_cast<std::size_t>(line - 1)] = joined;
    std::string text;
    for (const auto& x : lines) text += x + "\n";
    return errorOf(text);
  }
  std::string errorOf(const std::string& text) {
    std::ofstream(file_, std::ios::binary | std::ios::trunc) << text;
    auto r = readProfileCsv(file_);
    EXPECT_FALSE(r.ok()) << "accepted";
    return r.ok() ? "" : r.error().message;
  }

  std::string file_, text_;
};

TEST_F(ProfileCsv, RoundTripsExactly) {
  std::ofstream(file_, std::ios::binary) << text_;
  auto back = readProfileCsv(file_);
  ASSERT_TRUE(back.ok()) << back.error().message;
  const auto bins = plausibleBins();
  ASSERT_EQ(back->size(), bins.size());
  for (std::size_t k = 0; k < bins.size(); ++k) {
    EXPECT_EQ((*back)[k].n, bins[k].n);
    if (bins[k].n > 0) {
      EXPECT_EQ((*back)[k].phiMean, bins[k].phiMean);
      EXPECT_EQ((*back)[k].sigmaTheta, bins[k].sigmaTheta);
    }
  }
}

TEST_F(ProfileCsv, IndicesAndCountsAreIntegersInRange) {
  // Once cast from double to int (undefined behaviour) or accepted as a 17th column.
  EXPECT_THAT(errorWith(2, [](auto& f) { f[0] = "1e300"; }),
              HasSubstr("line 2: column 'i_phi': '1e300' is not a bin index 0 to 15"));
  EXPECT_THAT(errorWith(2, [](auto& f) { f[0] = "99"; }), HasSubstr("column 'i_phi': '99'"));
  EXPECT_THAT(errorWith(2, [](auto& f) { f[1] = "2.5"; }), HasSubstr("column 'i_theta'"));
  EXPECT_THAT(errorWith(2, [](auto& f) { f[2] = "1e300"; }), HasSubstr("column 'n': '1e300' is not a count"));
  EXPECT_THAT(errorWith(2, [](auto& f) { f[2] = "-5"; }), HasSubstr("column 'n'"));
}

TEST_F(ProfileCsv, EveryBinExactlyOnce) {
  EXPECT_THAT(errorWith(3, [](auto& f) { f[1] = "0"; }),
              HasSubstr("line 3: bin (0, 0) is given again (first on line 2)"));
  std::string shorter = text_.substr(0, text_.rfind('\n', text_.size() - 2) + 1);
  EXPECT_THAT(errorOf(shorter), HasSubstr("159 of the 160 bins are given; bin (15, 9) is missing"));
}

TEST_F(ProfileCsv, ValuesMustBePlausible) {
  EXPECT_THAT(errorWith(2, [](auto& f) { f[5] = "1e-300"; }),
              HasSubstr("column 'e_mean_mev': '1e-300' is not a plausible cluster energy"));
  EXPECT_THAT(errorWith(2, [](auto& f) { f[3] = "3.0"; }),
              HasSubstr("column 'phi_mean_rad': '3.0' lies outside its bin i_phi = 0"));
  EXPECT_THAT(errorWith(2, [](auto& f) { f[4] = "0.1"; }), HasSubstr("column 'theta_mean_rad'"));
  EXPECT_THAT(errorWith(2, [](auto& f) { f[6] = "1.5"; }), HasSubstr("column 'y_phi': '1.5' is not a sine"));
  EXPECT_THAT(errorWith(2, [](auto& f) { f[7] = "0"; }), HasSubstr("column 'sigma_phi'"));
  EXPECT_THAT(errorWith(2, [](auto& f) { f[5] = ""; }), HasSubstr("column 'e_mean_mev': empty, but the bin has"));
  // Bin (3, 4) is empty (n = 0): a value there is a contradiction.
  EXPECT_THAT(errorWith(2 + 3 * 10 + 4, [](auto& f) { f[5] = "600"; }), HasSubstr("without entries"));
}

TEST_F(ProfileCsv, LongFieldsAreNotEchoed) {
  const std::string message = errorWith(2, [](auto& f) { f[3] = std::string(10'000'000, '7'); });
  EXPECT_LT(message.size(), 300u);
  EXPECT_THAT(message, HasSubstr("(10000000 characters)"));
}

// A file of another kind is named by what it is, never by its raw bytes ("got '\x89HDF'").
TEST_F(ProfileCsv, FilesOfAnotherKindAreNamed) {
  const std::string hdf5 = errorOf(std::string("\x89HDF\r\n\x1a\n", 8) + std::string(64, '\0') + "\n");
  EXPECT_THAT(hdf5, HasSubstr("this is an HDF5 file (an event file?), not a profile CSV (fit --profile-out)"));
  EXPECT_THAT(hdf5, Not(HasSubstr("HDF'")));
  EXPECT_THAT(errorOf(R"({"format": "emcalign-alignment/1", "parameters": {}})"
                      "\n"),
              HasSubstr("this is a parameter file (its format: emcalign-alignment/1), not a profile CSV"));
  EXPECT_THAT(errorOf("run,event,beam_energy_mev,muon_veto\n"), HasSubstr("this is a CSV event file, not a profile"));
  // A profile with a wrong header is still told what its header should be.
  EXPECT_THAT(errorWith(1, [](auto& f) { f[2] = "entries"; }), HasSubstr("header: expected 'i_phi,i_theta,n,"));
}

TEST_F(ProfileCsv, ACutFileIsRefused) {
  EXPECT_THAT(errorOf(text_.substr(0, text_.size() - 5)), HasSubstr("no newline at its end"));
}

// The profiles of several runs merged are the profile of all their particles (a campaign
// groups runs this way), and σ_sys can be taken out afterwards.
TEST(ProfileMerge, EqualsOneFillOfAllParticles) {
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> phi(0.0, 2.0 * M_PI), theta(44.0 * deg, 136.0 * deg);
  std::normal_distribution<double> y(0.001, 0.02);
  Profiles all, a, b, c;
  for (int i = 0; i < 30000; ++i) {
    const ParticleResidual p{phi(rng), theta(rng), 600.0 + 10.0 * y(rng), y(rng), 0.5 * y(rng)};
    all.fill(p);
    (i % 7 == 0 ? a : i % 3 == 0 ? b : c).fill(p);
  }
  Profiles merged;
  merged.merge(a);
  merged.merge(b);
  merged.merge(c);
  ASSERT_EQ(merged.entries(), all.entries());
  const auto m = merged.bins(), o = all.bins();
  ASSERT_EQ(m.size(), o.size());
  int used = 0;
  for (std::size_t k = 0; k < m.size(); ++k) {
    ASSERT_EQ(m[k].n, o[k].n) << k;
    ASSERT_EQ(m[k].used, o[k].used) << k;
    if (!o[k].used) continue;
    ++used;
    EXPECT_NEAR(m[k].yPhi, o[k].yPhi, 1e-15);
    EXPECT_NEAR(m[k].yTheta, o[k].yTheta, 1e-15);
    EXPECT_NEAR(m[k].phiMean, o[k].phiMean, 1e-13);
    EXPECT_NEAR(m[k].energyMean, o[k].energyMean, 1e-10);
    EXPECT_NEAR(m[k].sigmaPhi, o[k].sigmaPhi, 1e-14);
    EXPECT_NEAR(m[k].sigmaTheta, o[k].sigmaTheta, 1e-14);
  }
  EXPECT_GT(used, 150);
  // Without σ_sys the errors are the statistical ones, smaller than with it.
  const auto stat = all.bins(0.0);
  for (std::size_t k = 0; k < stat.size(); ++k) {
    if (!o[k].used) continue;
    EXPECT_LT(stat[k].sigmaPhi, o[k].sigmaPhi);
    EXPECT_NEAR(std::hypot(stat[k].sigmaPhi, all.options().sigmaSys), o[k].sigmaPhi, 1e-15);
  }
  ProfileOptions other;
  other.phiBins = 8;
  EXPECT_THROW(merged.merge(Profiles(other)), std::invalid_argument);
}

}  // namespace
}  // namespace emcalign::calib
