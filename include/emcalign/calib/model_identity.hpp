#pragma once
// Which model a fit was made with, as data (docs/fit.md, "The model and its corrections"):
// the corrections file (by name, and SHA-256 when recorded) or none — the paper's model,
// possibly with its shower depth moved —, and the σ_sys choice. Payloads, `conditions list`,
// `conditions diff`, trend.md and a campaign's summary all say it through text(), and decide
// by its members, never by reading the words back.

#include <optional>
#include <string>
#include <vector>

#include "emcalign/calib/sigma_sys.hpp"

namespace emcalign::calib {

struct ModelIdentity {
  enum class Kind {
    Unsaid,       ///< the record does not say (a parameter file stored without its fit)
    Paper,        ///< the paper's model, no corrections (depthOffsetCm may move R(E, θ))
    Corrections,  ///< model corrections from a file or a grid directory
  };
  Kind kind = Kind::Unsaid;
  std::string corrections = {};                 ///< Corrections: the file or directory as it was named
  std::string correctionsSha256 = {};           ///< Corrections: its SHA-256; empty when not recorded
  double depthOffsetCm = 0.0;                   ///< Paper: the offset added to R(E, θ)
  std::optional<SigmaSysChoice> sigmaSys = {};  ///< none: not recorded

  [[nodiscard]] bool isPaper() const { return kind == Kind::Paper; }
  /// "the paper's model", "the paper's model, depth offset +1.5 cm", "corrections PATH";
  /// "" when unsaid.
  [[nodiscard]] std::string text() const;
  /// As a table cell: "paper's model", the corrections' file name; "" when unsaid.
  [[nodiscard]] std::string brief() const;
  /// text() with the σ_sys choice when recorded: "…; sigma_sys auto" or "…; sigma_sys 0.2 deg".
  [[nodiscard]] std::string textWithSigmaSys() const;
  /// The same model: kind, corrections, depth offset, and the SHA-256 where both record it
  /// (σ_sys is compared on its own: it sets the errors, not the values).
  [[nodiscard]] bool sameModel(const ModelIdentity& other) const;
};

/// `model` added to `models` unless one of them is the same model (sameModel): the distinct
/// models of IOVs, in the order first met.
void addDistinct(std::vector<ModelIdentity>& models, const ModelIdentity& model);

/// "auto", or the value in degrees ("0.2 deg").
std::string sigmaSysText(const SigmaSysChoice& choice);

}  // namespace emcalign::calib
