// libFuzzer target: the typed readers of the files the commands write and other commands (the
// report, trend, batch, conditions) read back — the fit result, check.json, compare.json, residuals.json, the
// campaign table, trend.json, a plan and a campaign's part of it, and a conditions payload with
// each of its lenient readers. Each input is read by all of them. Where the library has the
// writer of the record read (check, compare, residuals, table, campaign plan, payload), what reads is written back and
// must read again, the same when written once more (read–write–read).

#include "emcalign/apply/check_record.hpp"
#include "emcalign/apply/mc_comparison.hpp"
#include "emcalign/apply/residual_record.hpp"
#include "emcalign/calib/fit_record.hpp"
#include "emcalign/conddb/conditions.hpp"
#include "emcalign/io/json_files.hpp"
#include "emcalign/validation/calibration_campaign.hpp"
#include "emcalign/validation/campaign.hpp"
#include "emcalign/validation/campaign_plan.hpp"
#include "emcalign/validation/task_plan.hpp"
#include "emcalign/validation/trend.hpp"
#include "fuzz_support.hpp"

namespace {

using emcalign::io::Json;

// Written, read again, written again: the two writings are the same document.
template <typename Parse, typename Write>
void roundTrip(const Json& j, Parse parse, Write write) {
  auto first = parse(j, "fuzz.json");
  if (!first) {
    emcalign::fuzz::expectMessage(false, first.error().message);
    return;
  }
  const Json written = write(*first);
  auto again = parse(written, "again.json");
  if (!again) __builtin_trap();  // what it wrote, it cannot read
  if (write(*again) != written) __builtin_trap();
}

void payload(const Json& j) {
  using namespace emcalign;
  auto p = conddb::makePayload(j, 53.7, "fuzz.json");
  if (!p) {
    fuzz::expectMessage(false, p.error().message);
    return;
  }
  // The lenient readers of a payload read anything makePayload wrote without failing.
  (void)p->hash();
  (void)p->modelIdentity().textWithSigmaSys();
  (void)p->values();
  (void)p->selectedEvents();
  (void)p->inputDigests();
  (void)p->correctionsFile();
  (void)p->depthOffsetCm();
  if (auto s = p->sigmaSysChoice(); !s) fuzz::expectMessage(false, s.error().message);
  // A payload's parameter file is stored again as the same calibration.
  auto again = conddb::makePayload(p->parameterFile(), 53.7, "again.json");
  if (!again) __builtin_trap();
  if (again->values().size() != p->values().size()) __builtin_trap();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace emcalign;
  const std::string text(reinterpret_cast<const char*>(data), size);
  // A plan is read from its text (and refuses what is not one).
  if (auto plan = validation::parsePlan(text, "fuzz-plan.json"); !plan) {
    fuzz::expectMessage(false, plan.error().message);
  } else if (auto campaign = validation::parseCampaignPlan(plan->data, plan->path); !campaign) {
    fuzz::expectMessage(false, campaign.error().message);
  }
  auto j = io::parseJson(text, "fuzz.json");
  if (!j) {
    fuzz::expectMessage(false, j.error().message);
    return 0;
  }
  if (auto f = calib::parseFitRecord(*j, "fuzz.json"); !f) fuzz::expectMessage(false, f.error().message);
  if (auto t = validation::parseTrend(*j, "fuzz.json"); !t) fuzz::expectMessage(false, t.error().message);
  roundTrip(*j, validation::parseCampaignPlan,
            [](const validation::CampaignPlan& p) { return validation::campaignPlanJson(p); });
  roundTrip(*j, apply::parseCheckRecord, [](const apply::CheckRecord& r) { return apply::checkJson(r); });
  roundTrip(*j, apply::parseComparison, [](const apply::ComparisonRecord& r) { return apply::comparisonJson(r); });
  roundTrip(*j, apply::parseResiduals, [](const apply::ResidualRecord& r) { return apply::residualsJson(r); });
  roundTrip(*j, validation::parseTable, [](const validation::Table& t) { return validation::tableJson(t); });
  payload(*j);
  return 0;
}
