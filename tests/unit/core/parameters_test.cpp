#include "emcalign/core/parameters.hpp"

#include <algorithm>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

namespace emcalign {
namespace {

// A physical parameter that is a fit parameter too is that fit parameter: one quantity, one name.
TEST(Quantity, APhysicalFitParameterIsTheFitParameter) {
  for (Physical p : kAllPhysical) {
    const Quantity q(p);
    EXPECT_EQ(q.name(), name(p));
    EXPECT_EQ(q.dimension(), dimension(p)) << q;
    EXPECT_EQ(q.param().has_value(), paramFromName(name(p)).has_value()) << q;
  }
  EXPECT_EQ(Quantity(Physical::Dx), Quantity(Param::Dx));
  EXPECT_EQ(Quantity(Physical::BetaRel), Param::BetaRel);
  EXPECT_FALSE(Quantity(Physical::Beta).param());
  EXPECT_NE(Quantity(Physical::Beta), Param::Beta1);
}

TEST(Quantity, UnitsAndDirectionsComeFromTheType) {
  EXPECT_EQ(Quantity(Param::Dx).unit(), "cm");
  EXPECT_EQ(Quantity(Param::Beta1).unit(), "deg");  // dimensionless, written in degrees
  EXPECT_EQ(Quantity(Physical::DxRel).unit(), "cm");
  EXPECT_EQ(Quantity(Physical::Mu).unit(), "deg");
  std::vector<std::string> directions;
  for (Quantity q : kAllQuantities) {
    if (q.isDirection()) directions.emplace_back(q.name());
  }
  EXPECT_EQ(directions, (std::vector<std::string>{"psi", "tau"}));
}

// fit − truth of a direction is the nearest turn; of anything else the plain difference.
TEST(Quantity, ADirectionsDifferenceIsTheNearestTurn) {
  EXPECT_DOUBLE_EQ(Quantity(Physical::Psi).difference(179.0, -179.0), -2.0);
  EXPECT_DOUBLE_EQ(Quantity(Physical::Tau).difference(-170.0, 170.0), 20.0);
  EXPECT_DOUBLE_EQ(Quantity(Param::Alpha).difference(179.0, -179.0), 358.0);
  EXPECT_DOUBLE_EQ(Quantity(Param::Dx).difference(0.3, 0.5), -0.2);
}

// The 17 listed, in the order of the files: the 12, then beta, psi, mu, tau, dx_rel.
TEST(Quantity, TheListedQuantitiesAndTheirNames) {
  std::vector<std::string> names;
  for (Quantity q : kAllQuantities) names.emplace_back(q.name());
  EXPECT_EQ(names, (std::vector<std::string>{"alpha", "beta1", "beta2", "dx", "dy", "dz", "dp1", "dp2", "dp3", "dy_rel",
                                             "dz_rel", "beta_rel", "beta", "psi", "mu", "tau", "dx_rel"}));
  for (Quantity q : kAllQuantities) {
    const auto back = quantityFromName(q.name());
    ASSERT_TRUE(back) << q;
    EXPECT_EQ(*back, q);
  }
  EXPECT_FALSE(quantityFromName("phi"));
  EXPECT_FALSE(quantityFromName(""));
  EXPECT_FALSE(quantityFromName("Dx"));  // names are exact
}

// Keyed and sorted by name, as the tables keyed by name strings were; written as the name.
TEST(Quantity, OrdersFormatsAndWritesAsItsName) {
  std::map<Quantity, int> byName;
  for (Quantity q : kAllQuantities) byName[q] = 0;
  std::vector<std::string> sorted;
  for (const auto& [q, v] : byName) sorted.emplace_back(q.name());
  EXPECT_TRUE(std::is_sorted(sorted.begin(), sorted.end()));
  EXPECT_EQ(sorted.size(), kAllQuantities.size());
  EXPECT_EQ(fmt::format("{}|{:>6}", Quantity(Physical::Mu), Quantity(Param::Dx)), "mu|    dx");
  std::ostringstream os;
  os << Quantity(Param::DzRel);
  EXPECT_EQ(os.str(), "dz_rel");
  const nlohmann::json j = {{"parameter", Quantity(Physical::Tau)},
                            {"list", std::vector<Quantity>{Param::Alpha, Physical::Beta}}};
  EXPECT_EQ(j.dump(), R"({"list":["alpha","beta"],"parameter":"tau"})");
}

}  // namespace
}  // namespace emcalign
