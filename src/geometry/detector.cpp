#include "emcalign/geometry/detector.hpp"

#include <cmath>
#include <numbers>

#include <fmt/format.h>

#include "emcalign/core/units.hpp"

namespace emcalign::geometry {

using units::deg;

DetectorDescription DetectorDescription::sndDefault() {
  DetectorDescription d;
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
  for (std::size_t i = 0; i < layers.size(); ++i) {
    const auto& l = layers[i];
    if (!finite(l.rInner) || !finite(l.rOuter) || l.rInner <= 0.0 || l.rOuter <= l.rInner) {
      return Error{fmt::format("layers[{}]: need 0 < r_inner_cm < r_outer_cm, got {} and {}", i,
                               l.rInner, l.rOuter)};
    }
  }
  for (std::size_t i = 0; i < supports.size(); ++i) {
    const auto& s = supports[i];
    if (!finite(s.rInner) || !finite(s.rOuter) || s.rOuter <= s.rInner) {
      return Error{fmt::format("support_spheres[{}]: need r_inner_cm < r_outer_cm, got {} and {}",
                               i, s.rInner, s.rOuter)};
    }
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
      return Error{fmt::format("{}.r_inner_cm ({}) is inside {} (r_outer_cm {}): shells must be "
                               "ordered layer 1, layer 2, support sphere 1, layer 3, support sphere 2",
                               order[i].first, order[i].second->rInner, order[i - 1].first,
                               order[i - 1].second->rOuter)};
    }
  }
  if (!finite(thetaMin) || !finite(thetaMax) || thetaMin <= 0.0 || thetaMax >= std::numbers::pi ||
      thetaMax <= thetaMin) {
    return Error{fmt::format("theta_min_deg/theta_max_deg: need 0 < min < max < 180, got {} and {}",
                             thetaMin / deg, thetaMax / deg)};
  }
  if (countersPerRing.empty()) return Error{"counters_per_ring: must not be empty"};
  for (std::size_t i = 0; i < countersPerRing.size(); ++i) {
    const int n = countersPerRing[i];
    if (n < 4 || n % 4 != 0) {
      return Error{fmt::format(
          "counters_per_ring[{}] = {}: must be a positive multiple of 4, so that the parting "
          "plane x = 0 (phi = 90 and 270 deg) is a cell boundary",
          i, n)};
    }
  }
  const auto& m = material;
  if (!finite(m.radiationLength) || m.radiationLength <= 0.0) {
    return Error{fmt::format("shower.x0_cm must be positive, got {}", m.radiationLength)};
  }
  if (!finite(m.criticalEnergy) || m.criticalEnergy <= 0.0) {
    return Error{fmt::format("shower.critical_energy_mev must be positive, got {}", m.criticalEnergy)};
  }
  if (!finite(m.preshowerMaterial) || m.preshowerMaterial < 0.0) {
    return Error{fmt::format("shower.x_pre must be non-negative, got {}", m.preshowerMaterial)};
  }
  return {};
}

Vec3 Counter::centre() const {
  const double r = radius(), t = theta(), p = phi();
  return {r * std::sin(t) * std::cos(p), r * std::sin(t) * std::sin(p), r * std::cos(t)};
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
  counters_.reserve(static_cast<std::size_t>(3 * countersPerLayer_));
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
  const auto& d = description_;
  const double r = p.norm();
  int layer = 0;
  for (int l = 1; l <= 3; ++l) {
    if (d.layers[static_cast<std::size_t>(l - 1)].contains(r)) layer = l;
  }
  if (layer == 0) {
    if (r < d.r0()) return {Region::Inside, -1};
    if (r >= d.supports[1].rInner) {
      return {r < d.supports[1].rOuter ? Region::SupportSphere : Region::Outside, -1};
    }
    return {Region::SupportSphere, -1};
  }
  const double theta = std::atan2(std::hypot(p.x(), p.y()), p.z());
  if (theta < d.thetaMin || theta >= d.thetaMax) return {Region::Uncovered, -1};
  const int rings = d.ringCount();
  int ring = static_cast<int>(std::floor((theta - d.thetaMin) / d.ringWidth()));
  ring = std::clamp(ring, 0, rings - 1);
  double phi = std::atan2(p.y(), p.x());
  if (phi < 0.0) phi += 2.0 * std::numbers::pi;
  const int n = d.countersPerRing[static_cast<std::size_t>(ring)];
  int iphi = static_cast<int>(std::floor(phi / (2.0 * std::numbers::pi / n)));
  iphi = std::clamp(iphi, 0, n - 1);
  // Cells are split exactly at x = 0: keep a point on its own side of the parting plane
  // even when rounding puts φ on the other side of a 90°/270° edge.
  const Hemisphere side = hemisphereOf(p.x());
  const Counter* c = &counters_[static_cast<std::size_t>(counterIndex(layer, ring, iphi))];
  if (c->hemisphere != side) {
    const int quarter = n / 4;
    if (iphi == quarter - 1 || iphi == 3 * quarter - 1) {
      iphi += 1;
    } else if (iphi == quarter || iphi == 3 * quarter) {
      iphi -= 1;
    }
  }
  return {Region::Counter, counterIndex(layer, ring, iphi)};
}

}  // namespace emcalign::geometry
