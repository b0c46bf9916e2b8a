#pragma once
// The parts of a validation campaign (validation/campaign.hpp) that live in files of their own.

#include <vector>

#include "emcalign/core/parameters.hpp"
#include "emcalign/geometry/alignment_parameters.hpp"
#include "emcalign/report/campaign_plots.hpp"
#include "emcalign/validation/campaign.hpp"

namespace emcalign::validation {

/// A physical parameter's file unit (deg or cm, in native units).
inline double fileUnitOf(Physical p) { return geometry::PhysicalParameters::fileUnit(p); }

/// The figures' input: the quantities of the table, in its order and with its definitions
/// (the 12 fit parameters, then β, ψ, μ, τ, dx_rel), per sample in file units (campaign_table.cpp).
std::vector<report::CampaignSeries> campaignSeries(const std::vector<SampleResult>& samples, double r1);

}  // namespace emcalign::validation
