#pragma once
// Figures of the physics checks (apply/physics_checks.hpp; docs/checks.md): distributions
// before (filled) and after (open) the correction, as the paper's Figs. 9 and 10.
//  - acollinearity.png: Δφ and Δθ of the selected γγ events, with the Gaussian core widths;
//  - chi2.png: the kinematic-fit χ² of the selected π+π−π0 events, with the χ² density of the
//    fit's ndf for comparison.
// Data: NAME.dat (per panel a gnuplot index block: bin centre, before, after), script NAME.gp.

#include <string>
#include <vector>

#include "emcalign/apply/check_record.hpp"
#include "emcalign/core/result.hpp"

namespace emcalign::report {

struct BeforeAfterPanel {
  std::string xlabel;
  double low = 0.0, high = 1.0;
  int bins = 50;
  std::vector<double> before, after;
  std::string beforeLabel, afterLabel;  ///< the key (with the numbers to show; gnuplot enhanced text)
  int chi2Ndf = 0;                      ///< > 0: draw the χ² density of this ndf, scaled
  std::string unit;                     ///< of the x axis ("deg"), in the y label's bin width
};

/// A check's figure and the line `emcalign check` prints: the panels over the ranges of the
/// paper's Figs. 9 and 10 (Δφ ±6°, Δθ ±15°; the χ² of the converged fits, 0–30), their keys
/// and the summary with the numbers of check.json (apply::CheckRecord).
struct CheckFigure {
  std::string name;  ///< "acollinearity" or "chi2"
  std::string title;
  std::vector<BeforeAfterPanel> panels;
  std::string summary;
};
CheckFigure checkFigure(const apply::GammaGammaCheck& check, const apply::CheckRecord& record);
CheckFigure checkFigure(const apply::ThreePionCheck& check, const apply::CheckRecord& record);

/// Writes NAME.png (the panels side by side) into `dir`; its path.
Result<std::string> writeBeforeAfterPlot(const std::string& dir, const std::string& name, const std::string& title,
                                         const std::vector<BeforeAfterPanel>& panels);

}  // namespace emcalign::report
