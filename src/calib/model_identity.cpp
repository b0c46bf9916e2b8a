// The model of a fit as data, and its one wording (calib/model_identity.hpp).

#include "emcalign/calib/model_identity.hpp"

#include <algorithm>
#include <filesystem>

#include <fmt/format.h>

#include "emcalign/core/units.hpp"

namespace emcalign::calib {

std::string ModelIdentity::text() const {
  switch (kind) {
    case Kind::Unsaid:
      return {};
    case Kind::Paper:
      return depthOffsetCm != 0.0 ? fmt::format("the paper's model, depth offset {:+.3g} cm", depthOffsetCm)
                                  : std::string("the paper's model");
    case Kind::Corrections:
      break;
  }
  return "corrections " + corrections;
}

std::string ModelIdentity::brief() const {
  switch (kind) {
    case Kind::Unsaid:
      return {};
    case Kind::Paper:
      return "paper's model";
    case Kind::Corrections:
      break;
  }
  return std::filesystem::path(corrections).filename().string();
}

std::string ModelIdentity::textWithSigmaSys() const {
  if (!sigmaSys) return text();
  return fmt::format("{}; sigma_sys {}", text(), sigmaSysText(*sigmaSys));
}

bool ModelIdentity::sameModel(const ModelIdentity& other) const {
  if (kind != other.kind || corrections != other.corrections || depthOffsetCm != other.depthOffsetCm) return false;
  return correctionsSha256.empty() || other.correctionsSha256.empty() || correctionsSha256 == other.correctionsSha256;
}

void addDistinct(std::vector<ModelIdentity>& models, const ModelIdentity& model) {
  const auto same = [&](const ModelIdentity& m) { return m.sameModel(model); };
  if (std::none_of(models.begin(), models.end(), same)) models.push_back(model);
}

std::string sigmaSysText(const SigmaSysChoice& choice) {
  if (choice.method == SigmaSysMethod::Auto) return "auto";
  return fmt::format("{:g} deg", choice.value / units::deg);
}

}  // namespace emcalign::calib
