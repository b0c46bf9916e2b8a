#include "emcalign/geometry/detector.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <utility>

#include <fmt/format.h>

#include "emcalign/core/units.hpp"

namespace emcalign::geometry {

using units::deg;

namespace {
// Whether a φ cell edge (cos, sin), in the first quadrant, is at or below the angle of the
// in-quadrant point (u, v): the cross-product test of locate and of its table guesses.
bool edgePassed(const std::pair<double, double>& edge, double u, double v) {
  return u * edge.second - v * edge.first <= 0.0;
}
}  // namespace

DetectorDescription DetectorDescription::sndDefault() {
  DetectorDescription d;
  // The name is part of the description's digest, which plans and tags record: never reworded.
  d.name = "SND-like default (SPEC §2)";
  d.layers = {SphericalShell{32.8, 40.3}, SphericalShell{40.3, 52.7}, SphericalShell{53.7, 68.5}};
  d.supports = {SphericalShell{52.7, 53.7}, SphericalShell{68.5, 69.5}};
  d.thetaMin = 18.0 * deg;
  d.thetaMax = 162.0 * deg;
  // 16 rings of 9°: 40 counters (Δφ = 9°) inside 36°–144°, 16 (Δφ = 22.5°) outside.
  d.countersPerRing = {16, 16, 40, 40, 40, 40, 40, 40, 40, 40, 40, 40, 40, 40, 16, 16};
  d.material = ShowerMaterial{};
  return d;
}

Status DetectorDescription::validate() const {
  auto finite = [](double v) { return std::isfinite(v); };
  // A radius beyond the plausible range: the likely mistake is the unit.
  auto plausible = [](std::string_view key, double r) -> Status {
    if (r > kMaxRadius) {
      return Error{
          fmt::format("{} = {:.6g} cm is more than {} m: radii are in cm (given in mm?)", key, r, kMaxRadius / 100.0)};
    }
    if (r < kMinRadius) {
      return Error{fmt::format("{} = {:.6g} cm is less than {} cm: radii are in cm (given in m?)", key, r, kMinRadius)};
    }
    return {};
  };
  for (std::size_t i = 0; i < layers.size(); ++i) {
    const auto& l = layers[i];
    if (!finite(l.rInner) || !finite(l.rOuter) || l.rInner <= 0.0 || l.rOuter <= l.rInner) {
      return Error{
          fmt::format("layers[{}]: need 0 < r_inner_cm < r_outer_cm, got {:.6g} and {:.6g}", i, l.rInner, l.rOuter)};
    }
    if (Status s = plausible(fmt::format("layers[{}].r_inner_cm", i), l.rInner); !s) return s;
    if (Status s = plausible(fmt::format("layers[{}].r_outer_cm", i), l.rOuter); !s) return s;
  }
  for (std::size_t i = 0; i < supports.size(); ++i) {
    const auto& s = supports[i];
    if (!finite(s.rInner) || !finite(s.rOuter) || s.rOuter <= s.rInner) {
      return Error{fmt::format("support_spheres[{}]: need r_inner_cm < r_outer_cm, got {:.6g} and {:.6g}", i, s.rInner,
                               s.rOuter)};
    }
    if (Status st = plausible(fmt::format("support_spheres[{}].r_inner_cm", i), s.rInner); !st) return st;
    if (Status st = plausible(fmt::format("support_spheres[{}].r_outer_cm", i), s.rOuter); !st) return st;
  }
  // Radial order: layer 1, layer 2, sphere 1, layer 3, sphere 2 (shells may touch).
  const std::array<std::pair<const char*, const SphericalShell*>, 5> order = {{
      {"layers[0]", &layers[0]},
      {"layers[1]", &layers[1]},
      {"support_spheres[0]", &supports[0]},
      {"layers[2]", &layers[2]},
      {"support_spheres[1]", &supports[1]},
  }};
  for (std::size_t i = 1; i < order.size(); ++i) {
    if (order[i].second->rInner < order[i - 1].second->rOuter) {
      return Error{
          fmt::format("{}.r_inner_cm ({:.6g}) is inside {} (r_outer_cm {:.6g}): shells must be "
                      "ordered layer 1, layer 2, support sphere 1, layer 3, support sphere 2",
                      order[i].first, order[i].second->rInner, order[i - 1].first, order[i - 1].second->rOuter)};
    }
  }
  if (!finite(thetaMin) || !finite(thetaMax) || thetaMin <= 0.0 || thetaMax >= std::numbers::pi ||
      thetaMax <= thetaMin) {
    return Error{fmt::format("theta_min_deg/theta_max_deg: need 0 < min < max < 180, got {} and {}", thetaMin / deg,
                             thetaMax / deg)};
  }
  if (countersPerRing.empty()) return Error{"counters_per_ring: must not be empty"};
  if (countersPerRing.size() > static_cast<std::size_t>(kMaxRings)) {
    return Error{fmt::format("counters_per_ring: {} rings, at most {}", countersPerRing.size(), kMaxRings)};
  }
  for (std::size_t i = 0; i < countersPerRing.size(); ++i) {
    const int n = countersPerRing[i];
    if (n < 4 || n % 4 != 0 || n > kMaxCountersPerRing) {
      return Error{
          fmt::format("counters_per_ring[{}] = {}: must be a positive multiple of 4 (so that the parting plane x = 0, "
                      "phi = 90 and 270 deg, is a cell boundary) and at most {}",
                      i, n, kMaxCountersPerRing)};
    }
  }
  const auto& m = material;
  if (!finite(m.radiationLength) || m.radiationLength < 0.1 || m.radiationLength > 50.0) {
    return Error{
        fmt::format("shower.x0_cm = {:.6g}: a radiation length lies in [0.1, 50] cm (NaI: 2.56)", m.radiationLength)};
  }
  if (!finite(m.criticalEnergy) || m.criticalEnergy < 1.0 || m.criticalEnergy > 100.0) {
    return Error{fmt::format("shower.critical_energy_mev = {:.6g}: a critical energy lies in [1, 100] MeV (NaI: 13.16)",
                             m.criticalEnergy)};
  }
  if (!finite(m.preshowerMaterial) || m.preshowerMaterial < 0.0 || m.preshowerMaterial > 10.0) {
    return Error{fmt::format("shower.x_pre = {:.6g}: the material before the EMC lies in [0, 10] X0 (SND: 0.13)",
                             m.preshowerMaterial)};
  }
  return {};
}

Result<Calorimeter> Calorimeter::create(DetectorDescription description) {
  if (Status s = description.validate(); !s) return s.error();
  return Calorimeter(std::move(description));
}

Calorimeter::Calorimeter(DetectorDescription description) : description_(std::move(description)) {
  const auto& d = description_;
  ringOffsets_.reserve(d.countersPerRing.size());
  for (int n : d.countersPerRing) {
    ringOffsets_.push_back(countersPerLayer_);
    countersPerLayer_ += n;
  }
  const double dTheta = d.ringWidth();
  for (int l = 0; l < 3; ++l) {
    layerR2_[l][0] = d.layers[static_cast<std::size_t>(l)].rInner * d.layers[static_cast<std::size_t>(l)].rInner;
    layerR2_[l][1] = d.layers[static_cast<std::size_t>(l)].rOuter * d.layers[static_cast<std::size_t>(l)].rOuter;
  }
  outerR2_ = d.supports[1].rOuter * d.supports[1].rOuter;
  for (int ring = 0; ring <= d.ringCount(); ++ring) {
    const double c = std::cos(d.thetaMin + ring * dTheta);
    ringEdgeKeys_.push_back(c * std::abs(c));
  }
  for (int n : d.countersPerRing) {
    std::vector<std::pair<double, double>> edges;
    for (int j = 1; j < n / 4; ++j) {
      const double a = j * 2.0 * std::numbers::pi / n;
      edges.emplace_back(std::cos(a), std::sin(a));
    }
    quadrantEdges_.push_back(std::move(edges));
  }
  // The guesses must never be above the answer: each counts the edges passed at the bin's
  // other end, moved by a margin far beyond the rounding of the bin index. (cos θ bins are
  // bins of the signed square cos θ·|cos θ| that locate compares.)
  constexpr double kMargin = 1e-9;
  ringGuess_.resize(kCosBins);
  for (int i = 0; i < kCosBins; ++i) {
    const double top = -1.0 + 2.0 * (i + 1) / kCosBins + kMargin;
    int ring = 0;
    while (ring + 1 < d.ringCount() && ringEdgeKeys_[static_cast<std::size_t>(ring) + 1] >= top) ++ring;
    ringGuess_[static_cast<std::size_t>(i)] = static_cast<std::int16_t>(ring);
  }
  phiGuess_.resize(static_cast<std::size_t>(kPhiBins) * d.countersPerRing.size());
  for (std::size_t ring = 0; ring < d.countersPerRing.size(); ++ring) {
    const auto& edges = quadrantEdges_[ring];
    for (int i = 0; i < kPhiBins; ++i) {
      // The pseudo-angle t = v/(u + v) of the point (u, v) = (1 − t, t).
      const double t = std::max(0.0, static_cast<double>(i) / kPhiBins - kMargin);
      int below = 0;
      while (below < static_cast<int>(edges.size()) && edgePassed(edges[static_cast<std::size_t>(below)], 1.0 - t, t)) {
        ++below;
      }
      phiGuess_[ring * kPhiBins + static_cast<std::size_t>(i)] = static_cast<std::int16_t>(below);
    }
  }
  counters_.reserve(3 * static_cast<std::size_t>(countersPerLayer_));
  for (int layer = 1; layer <= 3; ++layer) {
    const auto& shell = d.layers[static_cast<std::size_t>(layer - 1)];
    for (int ring = 0; ring < d.ringCount(); ++ring) {
      const int n = d.countersPerRing[static_cast<std::size_t>(ring)];
      const double dPhi = 2.0 * std::numbers::pi / n;
      for (int iphi = 0; iphi < n; ++iphi) {
        Counter c;
        c.index = static_cast<int>(counters_.size());
        c.layer = layer;
        c.ring = ring;
        c.iphi = iphi;
        c.thetaMin = d.thetaMin + ring * dTheta;
        c.thetaMax = d.thetaMin + (ring + 1) * dTheta;
        c.phiMin = iphi * dPhi;
        c.phiMax = (iphi + 1) * dPhi;
        c.rInner = shell.rInner;
        c.rOuter = shell.rOuter;
        c.hemisphere = std::cos(c.phi()) > 0.0 ? Hemisphere::Plus : Hemisphere::Minus;
        const double r = c.radius(), t = c.theta(), p = c.phi();
        c.position = Vec3(r * std::sin(t) * std::cos(p), r * std::sin(t) * std::sin(p), r * std::cos(t));
        counters_.push_back(c);
      }
    }
  }
}

int Calorimeter::counterIndex(int layer, int ring, int iphi) const {
  const auto& d = description_;
  if (layer < 1 || layer > 3 || ring < 0 || ring >= d.ringCount()) return -1;
  if (iphi < 0 || iphi >= d.countersPerRing[static_cast<std::size_t>(ring)]) return -1;
  return countersPerLayer_ * (layer - 1) + ringOffsets_[static_cast<std::size_t>(ring)] + iphi;
}

Location Calorimeter::locate(const Vec3& p) const {
  // Called for every shower spot of the simulation, so written for speed: no angle, no
  // square root, no search with unpredictable branches (table guesses, see detector.hpp).
  const auto& d = description_;
  const double r2 = p.squaredNorm();
  int layer = 0;
  for (int l = 0; l < 3; ++l) {
    if (r2 >= layerR2_[l][0] && r2 < layerR2_[l][1]) layer = l + 1;
  }
  if (layer == 0) {
    if (r2 < layerR2_[0][0]) return {Region::Inside, -1};
    if (r2 >= outerR2_) return {Region::Outside, -1};
    return {Region::SupportSphere, -1};
  }
  // θ ∈ [θ_i, θ_i+1) ⇔ cos θ ∈ (cos θ_i+1, cos θ_i]; the edges' cosines decrease. Compared
  // as signed squares scaled by r²: cos θ_i ≥ z/r ⇔ c_i·|c_i|·r² ≥ z·|z|.
  const double zz = p.z() * std::abs(p.z());
  const int rings = d.ringCount();
  if (zz > ringEdgeKeys_.front() * r2 || zz <= ringEdgeKeys_.back() * r2) return {Region::Uncovered, -1};
  // The ring with edges[ring] ≥ cos θ > edges[ring + 1], from its table guess.
  const int cosBin = std::clamp(static_cast<int>((zz / r2 + 1.0) * (0.5 * kCosBins)), 0, kCosBins - 1);
  int ring = ringGuess_[static_cast<std::size_t>(cosBin)];
  while (ring + 1 < rings && ringEdgeKeys_[static_cast<std::size_t>(ring) + 1] * r2 >= zz) ++ring;
  // φ cell: the quadrant from the signs of x, y (as atan2 folded into [0, 2π) would place
  // it), then the number of cell edges at or below the in-quadrant angle (u, v) of the
  // point rotated by −q·90°, by cross products.
  const double x = p.x(), y = p.y();
  int quadrant;
  double u, v;
  if (y >= 0.0) {
    if (x > 0.0) {
      quadrant = 0;
      u = x;
      v = y;
    } else {
      quadrant = 1;
      u = y;
      v = -x;
    }
  } else {
    if (x < 0.0) {
      quadrant = 2;
      u = -x;
      v = -y;
    } else {
      quadrant = 3;
      u = -y;
      v = x;
    }
  }
  const auto& edges = quadrantEdges_[static_cast<std::size_t>(ring)];
  const int edgeCount = static_cast<int>(edges.size());
  // From the guess of the pseudo-angle v/(u + v), which grows with the angle.
  const double sum = u + v;
  const int phiBin = sum > 0.0 ? std::min(static_cast<int>(v / sum * kPhiBins), kPhiBins - 1) : 0;
  int lo = phiGuess_[static_cast<std::size_t>(ring) * kPhiBins + static_cast<std::size_t>(phiBin)];
  while (lo < edgeCount && edgePassed(edges[static_cast<std::size_t>(lo)], u, v)) ++lo;
  const int n = d.countersPerRing[static_cast<std::size_t>(ring)];
  const int quarter = n / 4;
  int iphi = quadrant * quarter + lo;
  // Cells are split exactly at x = 0: keep a point on its own side of the parting plane
  // even when rounding puts φ on the other side of a 90°/270° edge. (A cell is in s = +1
  // when its centre is, i.e. below 90° or from 270°.)
  const bool cellPlus = iphi < quarter || iphi >= 3 * quarter;
  if (cellPlus != (hemisphereOf(x) == Hemisphere::Plus)) {
    if (iphi == quarter - 1 || iphi == 3 * quarter - 1) {
      iphi += 1;
    } else if (iphi == quarter || iphi == 3 * quarter) {
      iphi -= 1;
    }
  }
  return {Region::Counter, countersPerLayer_ * (layer - 1) + ringOffsets_[static_cast<std::size_t>(ring)] + iphi};
}

}  // namespace emcalign::geometry
