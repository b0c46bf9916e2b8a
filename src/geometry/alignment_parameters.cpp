#include "emcalign/geometry/alignment_parameters.hpp"

#include <cmath>
#include <numbers>

#include <fmt/format.h>

#include "emcalign/core/units.hpp"

namespace emcalign::geometry {

namespace {
// γ_k of the three gap points, docs/contract.md §3.
constexpr std::array<double, 3> kGapAngles = {0.0, 2.0 * std::numbers::pi / 3.0, 4.0 * std::numbers::pi / 3.0};
}  // namespace

double AlignmentParameters::fileUnit(Param p) { return dimension(p) == Dimension::Angle ? units::deg : units::cm; }

double PhysicalParameters::fileUnit(Physical p) { return dimension(p) == Dimension::Angle ? units::deg : units::cm; }

Status validate(const AlignmentParameters& eta, double r1) {
  for (Param p : kAllParams) {
    if (!std::isfinite(eta[p])) return Error{fmt::format("parameter '{}' is not finite", name(p))};
  }
  const double b1 = eta[Param::Beta1], b2 = eta[Param::Beta2];
  if (b1 * b1 + b2 * b2 > 1.0) {
    return Error{
        fmt::format("beta1, beta2: sin(beta) = sqrt(beta1^2 + beta2^2) = {} exceeds 1 (values in files are "
                    "in degrees: sin(beta)*180/pi)",
                    std::hypot(b1, b2))};
  }
  const GapDecomposition g = decomposeGaps(eta);
  const double sinMu = std::sqrt(4.0 * g.t * g.t + g.u * g.u) / (2.0 * r1);
  if (sinMu > 1.0) {
    return Error{
        fmt::format("dp1, dp2, dp3: the gaps need sin(mu) = {} > 1 at R1 = {} cm; they differ by more than "
                    "the sphere's diameter",
                    sinMu, r1)};
  }
  return {};
}

Status checkPlausible(const AlignmentParameters& eta) {
  constexpr double kMaxAlphaDeg = 30.0, kMaxTiltDeg = 10.0, kMaxLengthCm = 10.0;
  for (Param p : kAllParams) {
    const double v = eta[p] / AlignmentParameters::fileUnit(p);
    if (dimension(p) == Dimension::Length) {
      if (!(std::abs(v) <= kMaxLengthCm)) {
        return Error{
            fmt::format("{} = {:.6g} cm is beyond the plausible ±{} cm of an alignment: lengths are in cm "
                        "(given in mm?)",
                        name(p), v, kMaxLengthCm)};
      }
      continue;
    }
    const double limit = p == Param::Alpha     ? kMaxAlphaDeg
                         : p == Param::BetaRel ? kMaxTiltDeg
                                               : std::sin(kMaxTiltDeg * units::deg) / units::deg;
    if (!(std::abs(v) <= limit)) {
      const std::string other = otherAngleUnits(v, limit);
      return Error{
          fmt::format("{} = {:.6g} deg is beyond the plausible ±{:.4g} deg of an alignment: angles are in "
                      "degrees{}",
                      name(p), v, limit, other.empty() ? std::string() : " (" + other + ")")};
    }
  }
  return {};
}

std::string otherAngleUnits(double v, double limit) {
  // What the number would be in degrees if the file's author wrote it in another unit.
  static const std::pair<const char*, double> kUnits[] = {{"mrad", 0.001 / units::deg * units::rad},
                                                          {"arcmin", 1.0 / 60.0},
                                                          {"arcsec", 1.0 / 3600.0},
                                                          {"rad", 1.0 / units::deg}};
  std::vector<std::string> plausible;
  for (const auto& [unit, toDeg] : kUnits) {
    const double d = v * toDeg;
    if (std::isfinite(d) && std::abs(d) <= limit && std::abs(d) >= 1e-3) {
      plausible.push_back(fmt::format("in {} it is {:.4g} deg", unit, d));
    }
  }
  return plausible.empty() ? std::string() : fmt::format("written in another unit? {}", fmt::join(plausible, ", "));
}

std::vector<std::string> unitWarnings(const AlignmentParameters& eta) {
  // Inside the plausible limits, but beyond any alignment the tool was validated for
  // (calib::validatedRanges: |α| ≤ 5°, β ≤ 0.5°, |β_rel| ≤ 0.2°) by a factor that another
  // unit explains.
  std::vector<std::string> out;
  for (Param p : {Param::Alpha, Param::Beta1, Param::Beta2, Param::BetaRel}) {
    const double v = eta[p] / AlignmentParameters::fileUnit(p);
    const double typical = p == Param::Alpha ? 5.0 : p == Param::BetaRel ? 1.0 : 2.0;
    if (!(std::abs(v) > typical)) continue;
    const std::string other = otherAngleUnits(v, typical);
    if (other.empty()) continue;
    out.push_back(fmt::format("{} = {:.6g} deg is larger than alignments are ({} deg at most in the validation); {}",
                              name(p), v, typical, other));
  }
  return out;
}

Result<PhysicalParameters> toPhysical(const AlignmentParameters& eta, double r1) {
  if (Status s = validate(eta, r1); !s) return s.error();
  return PhysicalParameters{physicalOf<double>(eta.values, r1)};
}

AlignmentParameters fromPhysical(const PhysicalParameters& phys, double r1) {
  AlignmentParameters eta;
  const double beta = phys[Physical::Beta], psi = phys[Physical::Psi];
  const double mu = phys[Physical::Mu], tau = phys[Physical::Tau];
  const double dxRel = phys[Physical::DxRel];
  eta[Param::Alpha] = phys[Physical::Alpha];
  eta[Param::Beta1] = std::sin(beta) * std::cos(psi);
  eta[Param::Beta2] = std::sin(beta) * std::sin(psi);
  eta[Param::Dx] = phys[Physical::Dx];
  eta[Param::Dy] = phys[Physical::Dy];
  eta[Param::Dz] = phys[Physical::Dz];
  const std::array<Param, 3> gaps = {Param::Dp1, Param::Dp2, Param::Dp3};
  for (std::size_t k = 0; k < 3; ++k) {
    eta[gaps[k]] = 2.0 * dxRel + 2.0 * r1 * std::sin(mu) * std::cos(kGapAngles[k] + tau);
  }
  eta[Param::DyRel] = phys[Physical::DyRel];
  eta[Param::DzRel] = phys[Physical::DzRel];
  eta[Param::BetaRel] = phys[Physical::BetaRel];
  return eta;
}

std::vector<std::string> warnings(const AlignmentParameters& eta, const ParamVector* errors) {
  std::vector<std::string> out;
  for (Param p : {Param::Dp1, Param::Dp2, Param::Dp3}) {
    const double v = eta[p] / units::cm;
    if (!(v < 0.0)) continue;
    if (!errors) {
      out.push_back(
          fmt::format("{} = {:.4f} cm is negative: the hemispheres overlap there (a calibration or "
                      "reconstruction problem to deal with before using these parameters)",
                      name(p), v));
      continue;
    }
    const double e = (*errors)[p] / units::cm;
    if (!std::isfinite(e) || v < -e) {
      out.push_back(
          fmt::format("{} = {:.4f} ± {:.4f} cm is negative beyond its error: the hemispheres overlap (a calibration or "
                      "reconstruction problem to deal with before using these parameters)",
                      name(p), v, e));
    }
  }
  return out;
}

}  // namespace emcalign::geometry
