// The tracking system of the simulation (sim/tracking.hpp): the line fit returns the docs/contract.md §5
// parameters of the line it saw, its resolution is the one the header derives from the
// configured hit resolutions, tracks with too few layers inside the sensitive length are
// lost, and the beam pipe scatters by the Highland angle.

#include "emcalign/sim/tracking.hpp"

#include <cmath>
#include <numbers>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "emcalign/core/units.hpp"

namespace emcalign::sim {
namespace {

using geometry::TrackLine;
using units::deg;

constexpr double kTwoPi = 2.0 * std::numbers::pi;

// The path of a docs/contract.md §5 line: its closest approach to the Z axis and its direction.
ChargedPath pathOf(const TrackLine& t) { return {t.closestApproach(), t.direction()}; }

double mean(const std::vector<double>& v) {
  double s = 0.0;
  for (double x : v) s += x;
  return s / static_cast<double>(v.size());
}

// Sample standard deviation (N − 1).
double stddev(const std::vector<double>& v) {
  const double m = mean(v);
  double s = 0.0;
  for (double x : v) s += (x - m) * (x - m);
  return std::sqrt(s / static_cast<double>(v.size() - 1));
}

// The lever arm of the header, L = √Σ(r_i − r̄)², and r̄.
double leverArm(const std::vector<double>& radii, double* meanRadius = nullptr) {
  const double rBar = mean(radii);
  double s = 0.0;
  for (double r : radii) s += (r - rBar) * (r - rBar);
  if (meanRadius) *meanRadius = rBar;
  return std::sqrt(s);
}

TrackingOptions withoutScattering() {
  TrackingOptions o;
  o.multipleScattering = false;
  return o;
}

TEST(Tracking, DefaultOptionsAreValidAndBadOnesAreRefused) {
  EXPECT_TRUE(TrackingOptions{}.validate().ok());
  auto refused = [](auto change) {
    TrackingOptions o;
    change(o);
    return !o.validate().ok();
  };
  EXPECT_TRUE(refused([](TrackingOptions& o) { o.sigmaRPhi = 0.0; }));
  EXPECT_TRUE(refused([](TrackingOptions& o) { o.sigmaZ = -0.01; }));
  EXPECT_TRUE(refused([](TrackingOptions& o) { o.halfLength = 0.0; }));
  EXPECT_TRUE(refused([](TrackingOptions& o) { o.layerRadii = {4.0, 6.0, 5.0}; }));
  EXPECT_TRUE(refused([](TrackingOptions& o) { o.layerRadii = {1.5, 4.0, 6.0}; }));  // inside the pipe
  EXPECT_TRUE(refused([](TrackingOptions& o) { o.minHits = 10; }));                  // 9 layers
  EXPECT_TRUE(refused([](TrackingOptions& o) { o.minHits = 1; }));
}

// With hit resolutions of 1e-12 cm (the smallest valid ones) the fit returns the line that
// made the hits, for random lines inside the acceptance, whichever point of the line the
// path starts from.
TEST(Tracking, PerfectHitsReproduceTheTrueLine) {
  TrackingOptions o = withoutScattering();
  o.sigmaRPhi = o.sigmaZ = 1e-12;
  ASSERT_TRUE(o.validate().ok());
  const TrackingSystem ts(o);
  Rng rng(101, 0);
  for (int i = 0; i < 500; ++i) {
    const TrackLine truth{rng.uniform(-8.0, 8.0), rng.uniform(-0.9, 0.9), rng.uniform(0.0, kTwoPi),
                          rng.uniform(55.0, 125.0) * deg};
    for (double along : {0.0, -2.0, 1.5}) {
      const ChargedPath path{truth.closestApproach() + along * truth.direction(), truth.direction()};
      const auto t = ts.measure(path, rng);
      ASSERT_TRUE(t) << "line " << i;
      EXPECT_GE(t->phi, 0.0);
      EXPECT_LT(t->phi, kTwoPi);
      EXPECT_NEAR(std::remainder(t->phi - truth.phi, kTwoPi), 0.0, 1e-9) << "line " << i;
      EXPECT_NEAR(t->theta, truth.theta, 1e-9) << "line " << i;
      EXPECT_NEAR(t->rho, truth.rho, 1e-9) << "line " << i;
      EXPECT_NEAR(t->z0, truth.z0, 1e-9) << "line " << i;
    }
  }
}

// The spread of the fitted parameters of radial tracks is the header's: σ_φ = σ_rφ/L,
// σ_θ = σ_z·sin²θ/L, and for the intercepts σ_rho = σ_rφ·k, σ_z0 = σ_z·k with
// k = √(1/n + r̄²/L²) (a straight-line fit through n points). Checked for the default
// resolutions and for others, at two polar angles. 4000 tracks give each σ to 1.1%; the
// tolerance is 5%. The means are zero within 4σ/√N.
TEST(Tracking, ResolutionFollowsTheConfiguredHitResolutions) {
  struct Resolution {
    double rPhi, z;
  };
  for (const Resolution hit : {Resolution{0.0316, 0.0365}, Resolution{0.08, 0.01}}) {
    for (const double theta : {90.0 * deg, 55.0 * deg}) {
      TrackingOptions o = withoutScattering();
      o.sigmaRPhi = hit.rPhi;
      o.sigmaZ = hit.z;
      const TrackingSystem ts(o);
      double rBar = 0.0;
      const double lever = leverArm(o.layerRadii, &rBar);
      const double k = std::sqrt(1.0 / static_cast<double>(o.layerRadii.size()) + rBar * rBar / (lever * lever));
      const double sin2 = std::sin(theta) * std::sin(theta);
      Rng rng(102, 0);
      constexpr int kTracks = 4000;
      std::vector<double> dPhi, dTheta, dRho, dZ0;
      for (int i = 0; i < kTracks; ++i) {
        const TrackLine truth{0.0, 0.0, rng.uniform(0.0, kTwoPi), theta};
        const auto t = ts.measure(pathOf(truth), rng);
        ASSERT_TRUE(t);
        dPhi.push_back(std::remainder(t->phi - truth.phi, kTwoPi));
        dTheta.push_back(t->theta - theta);
        dRho.push_back(t->rho);
        dZ0.push_back(t->z0);
      }
      const struct {
        const char* name;
        const std::vector<double>& values;
        double sigma;
      } expected[] = {{"phi", dPhi, hit.rPhi / lever},
                      {"theta", dTheta, hit.z * sin2 / lever},
                      {"rho", dRho, hit.rPhi * k},
                      {"z0", dZ0, hit.z * k}};
      for (const auto& e : expected) {
        SCOPED_TRACE(::testing::Message()
                     << e.name << ", σ_rφ " << hit.rPhi << ", σ_z " << hit.z << ", θ " << theta / deg);
        EXPECT_NEAR(stddev(e.values) / e.sigma, 1.0, 0.05);
        EXPECT_NEAR(mean(e.values), 0.0, 4.0 * e.sigma / std::sqrt(kTracks));
      }
    }
  }
  // The header's numbers for the defaults: σ_φ = 0.26°, σ_θ = 0.30° at θ = 90°.
  const TrackingOptions defaults;
  EXPECT_NEAR(defaults.sigmaRPhi / leverArm(defaults.layerRadii) / deg, 0.26, 0.005);
  EXPECT_NEAR(defaults.sigmaZ / leverArm(defaults.layerRadii) / deg, 0.30, 0.005);
}

// A hit counts when the line crosses a layer within |z| ≤ halfLength; fewer than minHits
// hits: no track. From the origin the layer at r is crossed at z = r·cotθ: with cotθ =
// 20/7.0 the layers at 4.0–6.7 cm (4 hits) are inside, with cotθ = 20/6.0 only 3 are.
TEST(Tracking, TracksWithTooFewLayersInsideTheSensitiveLengthAreLost) {
  const TrackingSystem ts(withoutScattering());
  Rng rng(103, 0);
  const double fourLayers = std::atan2(7.0, 20.0), threeLayers = std::atan2(6.0, 20.0);
  for (const double phi : {10.0 * deg, 200.0 * deg}) {
    EXPECT_TRUE(ts.measure(pathOf({0.0, 0.0, phi, fourLayers}), rng));
    EXPECT_FALSE(ts.measure(pathOf({0.0, 0.0, phi, threeLayers}), rng));
    // Backwards, the same.
    EXPECT_TRUE(ts.measure(pathOf({0.0, 0.0, phi, std::numbers::pi - fourLayers}), rng));
    EXPECT_FALSE(ts.measure(pathOf({0.0, 0.0, phi, std::numbers::pi - threeLayers}), rng));
    // Along the beam: no layer crossed at all.
    EXPECT_FALSE(ts.measure({Vec3::Zero(), Vec3::UnitZ()}, rng));
    // A vertex outside the sensitive length: every crossing is at |z| > 20 cm.
    EXPECT_FALSE(ts.measure(pathOf({25.0, 0.0, phi, 90.0 * deg}), rng));
    EXPECT_TRUE(ts.measure(pathOf({15.0, 0.0, phi, 90.0 * deg}), rng));
  }
  // The threshold is the configured one: 3 hits are a track with minHits = 3.
  TrackingOptions three = withoutScattering();
  three.minHits = 3;
  const auto t = TrackingSystem(three).measure(pathOf({0.0, 0.0, 10.0 * deg, threeLayers}), rng);
  ASSERT_TRUE(t);
  EXPECT_NEAR(t->theta, threeLayers, 0.05);  // three hits: still a fit of that line
}

// Multiple scattering in the beam pipe: the path leaves from the pipe (r = 2 cm) on the
// original line, turned by a Gaussian angle of projected width θ0 (Highland, with the
// thickness crossed at the track's incidence, x = t/(sinθ·X0) for a radial track).
TEST(Tracking, BeamPipeScatteringHasTheHighlandWidth) {
  const TrackingOptions o;
  const TrackingSystem ts(o);
  Rng rng(104, 0);
  for (const double theta : {90.0 * deg, 50.0 * deg}) {
    for (const double momentum : {40.0, 150.0}) {
      const double x = o.beamPipeThickness / std::sin(theta) / o.beamPipeRadiationLength;
      const double theta0 = 13.6 / momentum * std::sqrt(x) * (1.0 + 0.038 * std::log(x));
      std::vector<double> across;  // deflection along (−sinφ, cosφ, 0), ⊥ to the track
      constexpr int kTracks = 4000;
      for (int i = 0; i < kTracks; ++i) {
        const double phi = rng.uniform(0.0, kTwoPi);
        const Vec3 vertex(0.02, -0.01, 0.5);
        const Vec3 d = geometry::pointAt(1.0, theta, phi);
        const ChargedPath p = ts.scatter(vertex, d, momentum, 1.0, rng);
        ASSERT_NEAR(std::hypot(p.point.x(), p.point.y()), o.beamPipeRadius, 1e-12);
        ASSERT_NEAR((p.point - vertex).cross(d).norm(), 0.0, 1e-12);  // on the original line
        ASSERT_NEAR(p.direction.norm(), 1.0, 1e-12);
        across.push_back(p.direction.dot(Vec3(-std::sin(phi), std::cos(phi), 0.0)));
      }
      SCOPED_TRACE(::testing::Message() << "θ " << theta / deg << "°, p " << momentum << " MeV");
      EXPECT_NEAR(stddev(across) / theta0, 1.0, 0.05);
      EXPECT_NEAR(mean(across), 0.0, 4.0 * theta0 / std::sqrt(kTracks));
    }
  }
  // Switched off: the path is the vertex and the direction, untouched.
  TrackingOptions off;
  off.multipleScattering = false;
  const Vec3 d = geometry::pointAt(1.0, 70.0 * deg, 1.0);
  const ChargedPath p = TrackingSystem(off).scatter(Vec3::Zero(), d, 20.0, 0.5, rng);
  EXPECT_EQ(p.point, Vec3::Zero());
  EXPECT_EQ(p.direction, d);
}

}  // namespace
}  // namespace emcalign::sim
