#pragma once
// Small statistics shared by the analyses.

#include <vector>

namespace emcalign {

/// The median of the finite values (the mean of the two middle ones for an even count);
/// NaN when there is none.
double median(std::vector<double> values);

}  // namespace emcalign
