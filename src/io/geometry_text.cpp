#include "emcalign/io/geometry_text.hpp"

#include <cmath>

#include <fmt/format.h>

#include "emcalign/core/text.hpp"
#include "emcalign/core/units.hpp"
#include "emcalign/geometry/alignment_transform.hpp"

namespace emcalign::io {

namespace {

using namespace emcalign::geometry;
using units::cm;
using units::deg;

const char* unitName(Dimension d) { return d == Dimension::Angle ? "deg" : "cm"; }

}  // namespace

Json detectorSummaryJson(const Calorimeter& calo) {
  const auto& d = calo.description();
  Json layers = Json::array();
  for (int l = 1; l <= 3; ++l) {
    const auto& s = d.layers[static_cast<std::size_t>(l - 1)];
    layers.push_back({{"layer", l},
                      {"counters", calo.countersPerLayer()},
                      {"r_inner_cm", s.rInner / cm},
                      {"r_outer_cm", s.rOuter / cm}});
  }
  Json rings = Json::array();
  for (int r = 0; r < d.ringCount(); ++r) {
    const int n = d.countersPerRing[static_cast<std::size_t>(r)];
    rings.push_back({{"ring", r},
                     {"theta_min_deg", (d.thetaMin + r * d.ringWidth()) / deg},
                     {"theta_max_deg", (d.thetaMin + (r + 1) * d.ringWidth()) / deg},
                     {"counters", n},
                     {"dphi_deg", 360.0 / n}});
  }
  return {{"name", d.name},
          {"counters", calo.size()},
          {"layers", layers},
          {"r0_cm", d.r0() / cm},
          {"r1_cm", d.r1() / cm},
          {"rp3_cm", d.rp3() / cm},
          {"theta_min_deg", d.thetaMin / deg},
          {"theta_max_deg", d.thetaMax / deg},
          {"rings", rings}};
}

std::string detectorSummaryText(const Calorimeter& calo) {
  const auto& d = calo.description();
  std::string out = fmt::format("Detector: {}\n", d.name);
  out += fmt::format("Counters: {} ({} per layer, {} of {:.4g} deg from {:.4g} to {:.4g} deg)\n", calo.size(),
                     calo.countersPerLayer(), counted(d.ringCount(), "ring"), d.ringWidth() / deg, d.thetaMin / deg,
                     d.thetaMax / deg);
  out += fmt::format("  {:<22} {:>10} {:>10}\n", "shell", "r_in, cm", "r_out, cm");
  const char* names[] = {"layer 1", "layer 2", "support sphere 1", "layer 3", "support sphere 2"};
  const SphericalShell* shells[] = {&d.layers[0], &d.layers[1], &d.supports[0], &d.layers[2], &d.supports[1]};
  for (int i = 0; i < 5; ++i) {
    out += fmt::format("  {:<22} {:>10.2f} {:>10.2f}\n", names[i], shells[i]->rInner / cm, shells[i]->rOuter / cm);
  }
  out += fmt::format("R0 = {:.2f} cm (EMC inner radius), R1 = {:.2f} cm, R_p3 = {:.2f} cm\n", d.r0() / cm, d.r1() / cm,
                     d.rp3() / cm);
  out += "Rings (counters per ring):";
  for (int n : d.countersPerRing) out += fmt::format(" {}", n);
  return out + fmt::format("\nShower depth: X0 = {} cm, Ec = {} MeV, x_pre = {} X0\n", d.material.radiationLength,
                           d.material.criticalEnergy, d.material.preshowerMaterial);
}

Result<std::string> alignmentTableText(const AlignmentParameters& eta, const DetectorDescription& detector) {
  const double r1 = detector.r1();
  auto phys = toPhysical(eta, r1);
  if (!phys) return phys.error();
  std::string out = fmt::format("{:<10} {:>14}  {:<4}    {:<10} {:>14}  {:<4}\n", "fit set", "value", "unit",
                                "physical", "value", "unit");
  for (std::size_t i = 0; i < kNumParams; ++i) {
    const auto p = kAllParams[i];
    const auto q = static_cast<Physical>(i);
    out += fmt::format("{:<10} {:>14}  {:<4}    {:<10} {:>14}  {:<4}\n", name(p),
                       fixed(eta[p] / AlignmentParameters::fileUnit(p), 6), unitName(dimension(p)), name(q),
                       fixed((*phys)[q] / PhysicalParameters::fileUnit(q), 6), unitName(dimension(q)));
  }
  out += fmt::format("(beta1, beta2 are sin(beta)cos(psi), sin(beta)sin(psi) written in degrees; R1 = {} cm)\n",
                     r1 / units::cm);
  auto t = AlignmentTransform::create(eta, AlignmentRadii::of(detector));
  if (t && t->layer3RuleActive()) {
    out += fmt::format("Layer 3: dx_rel - R_p3*sin(mu) < 0, so layer 3 uses mu3 = asin(dx_rel/R_p3) = {} deg\n",
                       fixed(std::asin((*phys)[Physical::DxRel] / detector.rp3()) / units::deg, 6));
  }
  return out;
}

}  // namespace emcalign::io
