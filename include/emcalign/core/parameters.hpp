#pragma once
// The 12 alignment (fit) parameters η, indexed by `Param`, in the order and with the names
// of docs/contract.md §3. Code indexes them through this enum, never through a bare number.

#include <array>
#include <cmath>
#include <cstddef>
#include <optional>
#include <ostream>
#include <string>
#include <string_view>

#include <fmt/format.h>

namespace emcalign {

enum class Param : std::size_t {
  Alpha,  ///< rotation of the whole EMC about Z (rad)
  Beta1,  ///< sinβ·cosψ, dimensionless (files: degrees, value·180/π)
  Beta2,  ///< sinβ·sinψ, dimensionless (files: degrees, value·180/π)
  Dx,     ///< common shift ξ (cm)
  Dy,
  Dz,
  Dp1,    ///< gap between the hemispheres at R1·(0, cos γ, −sin γ), γ = 0° (cm)
  Dp2,    ///< … γ = 120° (cm)
  Dp3,    ///< … γ = 240° (cm)
  DyRel,  ///< relative shift of the halves (cm), hemisphere s moves by s·dy_rel
  DzRel,
  BetaRel,  ///< relative rotation about X (rad), hemisphere s turns by s·β_rel
};

inline constexpr std::size_t kNumParams = 12;

inline constexpr std::size_t index(Param p) { return static_cast<std::size_t>(p); }

inline constexpr std::array<Param, kNumParams> kAllParams = {Param::Alpha, Param::Beta1, Param::Beta2, Param::Dx,
                                                             Param::Dy,    Param::Dz,    Param::Dp1,   Param::Dp2,
                                                             Param::Dp3,   Param::DyRel, Param::DzRel, Param::BetaRel};

/// The exact names of docs/contract.md §3 (file keys, table rows).
inline constexpr std::array<std::string_view, kNumParams> kParamNames = {
    "alpha", "beta1", "beta2", "dx", "dy", "dz", "dp1", "dp2", "dp3", "dy_rel", "dz_rel", "beta_rel"};

inline constexpr std::string_view name(Param p) { return kParamNames[index(p)]; }

/// Whether a parameter is an angle (written in degrees in files) or a length (cm).
/// beta1 and beta2 are dimensionless but written as degrees (docs/contract.md §3).
enum class Dimension { Angle, Length };

/// The name of a dimension's file unit: "deg" or "cm".
inline constexpr std::string_view fileUnitName(Dimension d) { return d == Dimension::Angle ? "deg" : "cm"; }

inline constexpr Dimension dimension(Param p) {
  switch (p) {
    case Param::Alpha:
    case Param::Beta1:
    case Param::Beta2:
    case Param::BetaRel:
      return Dimension::Angle;
    default:
      return Dimension::Length;
  }
}

inline std::optional<Param> paramFromName(std::string_view n) {
  for (Param p : kAllParams) {
    if (name(p) == n) return p;
  }
  return std::nullopt;
}

/// The physical parameter set of docs/contract.md §3 (also accepted as input).
enum class Physical : std::size_t {
  Alpha,
  Beta,
  Psi,
  Dx,
  Dy,
  Dz,
  Mu,
  Tau,
  DxRel,
  DyRel,
  DzRel,
  BetaRel,
};

inline constexpr std::size_t index(Physical p) { return static_cast<std::size_t>(p); }

inline constexpr std::array<std::string_view, kNumParams> kPhysicalNames = {
    "alpha", "beta", "psi", "dx", "dy", "dz", "mu", "tau", "dx_rel", "dy_rel", "dz_rel", "beta_rel"};

inline constexpr std::string_view name(Physical p) { return kPhysicalNames[index(p)]; }

inline constexpr std::array<Physical, kNumParams> kAllPhysical = {
    Physical::Alpha, Physical::Beta, Physical::Psi,   Physical::Dx,    Physical::Dy,    Physical::Dz,
    Physical::Mu,    Physical::Tau,  Physical::DxRel, Physical::DyRel, Physical::DzRel, Physical::BetaRel};

/// The physical parameters that are not fit parameters: what a fit result calls "derived"
/// (docs/contract.md §3), in the order files and tables list them.
inline constexpr std::array<Physical, 5> kDerivedParams = {Physical::Beta, Physical::Psi, Physical::Mu, Physical::Tau,
                                                           Physical::DxRel};

/// ψ and τ: directions, defined modulo 360° (and only where their magnitude β, μ is not 0).
constexpr bool isDirection(Physical p) { return p == Physical::Psi || p == Physical::Tau; }

inline std::optional<Physical> physicalFromName(std::string_view n) {
  for (Physical p : kAllPhysical) {
    if (name(p) == n) return p;
  }
  return std::nullopt;
}

inline constexpr Dimension dimension(Physical p) {
  switch (p) {
    case Physical::Alpha:
    case Physical::Beta:
    case Physical::Psi:
    case Physical::Mu:
    case Physical::Tau:
    case Physical::BetaRel:
      return Dimension::Angle;
    default:
      return Dimension::Length;
  }
}

/// One quantity a table or a trend lists: a fit parameter (Param) or one of the physical set
/// (β, ψ, μ, τ, dx_rel, and those that are fit parameters too, which it holds as the Param).
/// Its name, file unit and whether it is a direction come from the type, never from a string
/// typed again; it compares and orders by name, as tables keyed by name did.
class Quantity {
 public:
  constexpr Quantity(Param p) : param_(p) {}  // NOLINT(google-explicit-constructor): a Param is one
  constexpr Quantity(Physical p) {            // NOLINT(google-explicit-constructor): so is a Physical
    switch (p) {
      case Physical::Alpha:
        param_ = Param::Alpha;
        break;
      case Physical::Dx:
        param_ = Param::Dx;
        break;
      case Physical::Dy:
        param_ = Param::Dy;
        break;
      case Physical::Dz:
        param_ = Param::Dz;
        break;
      case Physical::DyRel:
        param_ = Param::DyRel;
        break;
      case Physical::DzRel:
        param_ = Param::DzRel;
        break;
      case Physical::BetaRel:
        param_ = Param::BetaRel;
        break;
      default:
        physical_ = p;
    }
  }
  /// docs/contract.md §3's name ("dx", "beta_rel", "psi").
  [[nodiscard]] constexpr std::string_view name() const {
    return param_ ? emcalign::name(*param_) : emcalign::name(*physical_);
  }
  [[nodiscard]] constexpr Dimension dimension() const {
    return param_ ? emcalign::dimension(*param_) : emcalign::dimension(*physical_);
  }
  /// The file unit: "deg" or "cm".
  [[nodiscard]] constexpr std::string_view unit() const { return fileUnitName(dimension()); }
  /// ψ or τ: defined modulo 360°.
  [[nodiscard]] constexpr bool isDirection() const { return physical_ && emcalign::isDirection(*physical_); }
  /// The fit parameter it is, if it is one.
  [[nodiscard]] constexpr std::optional<Param> param() const { return param_; }
  /// a − b in file units: for a direction, the nearest turn.
  [[nodiscard]] double difference(double a, double b) const {
    const double d = a - b;
    return isDirection() ? d - 360.0 * std::round(d / 360.0) : d;
  }
  constexpr bool operator==(const Quantity& o) const { return name() == o.name(); }
  constexpr bool operator<(const Quantity& o) const { return name() < o.name(); }

 private:
  std::optional<Param> param_;
  std::optional<Physical> physical_;
};

/// What tables, trends and the conditions database list: the 12 fit parameters, then the
/// derived β, ψ, μ, τ, dx_rel (kDerivedParams), in this order.
inline constexpr std::array<Quantity, kNumParams + kDerivedParams.size()> kAllQuantities = {
    Param::Alpha,   Param::Beta1,  Param::Beta2, Param::Dx,     Param::Dy,      Param::Dz,
    Param::Dp1,     Param::Dp2,    Param::Dp3,   Param::DyRel,  Param::DzRel,   Param::BetaRel,
    Physical::Beta, Physical::Psi, Physical::Mu, Physical::Tau, Physical::DxRel};

/// A Quantity is written as its name in JSON (nlohmann::json finds this by argument lookup).
template <class Json>
void to_json(Json& j, const Quantity& q) {
  j = std::string(q.name());
}

inline std::ostream& operator<<(std::ostream& os, const Quantity& q) { return os << q.name(); }

/// A name of docs/contract.md §3 (a fit parameter's or a physical one's).
inline std::optional<Quantity> quantityFromName(std::string_view n) {
  if (auto p = paramFromName(n)) return Quantity(*p);
  if (auto p = physicalFromName(n)) return Quantity(*p);
  return std::nullopt;
}

}  // namespace emcalign

/// A Quantity is formatted as its name.
template <>
struct fmt::formatter<emcalign::Quantity> : fmt::formatter<std::string_view> {
  template <class Context>
  auto format(const emcalign::Quantity& q, Context& ctx) const {
    return fmt::formatter<std::string_view>::format(q.name(), ctx);
  }
};
