#include "calib/channel_gains.hpp"

#include <algorithm>
#include <cmath>

#include "calib/site_calibration.hpp"
#include "common/statistics.hpp"

namespace dronetrack::calib {

std::vector<Estimate> estimate_channel_gains(const std::vector<std::vector<double>>& levels_db,
                                             double floor_db) {
  std::vector<std::vector<double>> differences;  // per channel, per usable stretch
  for (const auto& stretch : levels_db) {
    if (stretch.empty()) continue;
    const bool usable = std::all_of(stretch.begin(), stretch.end(), [&](double level) {
      return std::isfinite(level) && level > floor_db;
    });
    if (!usable) continue;
    if (differences.empty()) differences.resize(stretch.size());
    if (stretch.size() != differences.size()) continue;
    double mean = 0.0;
    for (double level : stretch) mean += level / static_cast<double>(stretch.size());
    for (std::size_t i = 0; i < stretch.size(); ++i) differences[i].push_back(stretch[i] - mean);
  }
  std::vector<Estimate> out;
  if (differences.empty() || differences[0].size() < 3) return out;
  const auto count = static_cast<double>(differences[0].size());
  for (const auto& channel : differences) {
    Estimate estimate;
    estimate.value = median(channel);
    std::vector<double> deviations;
    for (double value : channel) deviations.push_back(std::abs(value - estimate.value));
    // The median's std is sqrt(pi / 2) times the mean's for Gaussian scatter.
    estimate.std = 1.2533 * 1.4826 * median(deviations) / std::sqrt(count);
    estimate.prior_std = 0.0;  // no prior: the levels alone
    estimate.excited = true;
    out.push_back(estimate);
  }
  return out;
}

}  // namespace dronetrack::calib
