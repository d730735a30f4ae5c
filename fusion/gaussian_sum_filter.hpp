#pragma once
// Seed 003's Gaussian-sum filter (SPEC 4.6): a track started from ONE array holds several
// Gaussians (EKFs on the 9-state model) spaced along the DOA's locus, every hypothesis_spacing_m,
// hypotheses_per_side per branch (a ray; a ray and its mirror image; the two branches of a cone on
// the source plane), with equal weights a_i = 1 / N (eq. 6). Each DOA updates every Gaussian and
// multiplies its weight by its own innovation likelihood N(nu_i; 0, S_i) (eq. 9); a weight below
// gamma / N is pruned (eq. 10). Gaussians that come within merge_d2 of each other (the range is
// resolved between them) merge into their moment-matched Gaussian. What the tracker sees (mean,
// covariance, the innovation it gates on) is the moment-matched mixture, so a track whose range
// is open reports the wide covariance it has. The false mirror side keeps its weight while the
// geometry cannot tell the sides apart (a platform on a straight line sees the same cone angles
// from both) and loses it once the platform turns.
// Everything is allocated at construction; nothing per measurement.
#include <memory>
#include <vector>

#include "fusion/track_filter.hpp"

namespace dronetrack::fusion {

class GaussianSumFilter final : public TrackFilter {
 public:
  explicit GaussianSumFilter(const FilterSettings& settings);

  // One Gaussian of weight 1 (a track a triangulation started).
  void initialise(const StateVector& mean, const StateCovariance& covariance) override;
  bool initialise_from_bearing(const BearingLocus& locus) override;
  void predict(double dt_s) override;
  FilterStatus innovation(const DoaMeasurementModel& model, const MeasurementCovariance& noise,
                          Innovation& out) override;
  FilterStatus update(const Innovation& innovation, const Measurement& z) override;
  const StateVector& mean() const override { return mean_; }
  const StateCovariance& covariance() const override { return covariance_; }
  int hypothesis_count() const override { return count_; }

  // Inspection: each live hypothesis's weight, mean and the branch of the locus it started on.
  double weight(int hypothesis) const { return weight_[static_cast<std::size_t>(hypothesis)]; }
  const StateVector& hypothesis_mean(int hypothesis) const;
  int branch(int hypothesis) const { return branch_[static_cast<std::size_t>(hypothesis)]; }
  // Total weight of the hypotheses started on `branch` (0 when all are pruned).
  double branch_weight(int branch) const;

 private:
  void remove(int hypothesis);
  void prune_and_merge();
  void combine();
  // P(speed <= one_array.max_speed_mps) of a hypothesis, along its mean velocity.
  double speed_plausibility(int hypothesis) const;

  FilterSettings settings_;
  std::vector<std::unique_ptr<TrackFilter>> components_;  // [0, count_) live
  std::vector<double> weight_;                            // the bearings' (eq. 9, on a common S)
  std::vector<double> effective_;  // weight_ times speed_plausibility, normalised: reported
  std::vector<int> branch_;
  std::vector<double> log_likelihood_;
  std::vector<Innovation> innovations_;
  std::vector<char> innovation_ok_;
  int count_ = 0;
  MeasurementCovariance noise_ = MeasurementCovariance::Zero();
  StateVector mean_ = StateVector::Zero();
  StateCovariance covariance_ = StateCovariance::Identity();
};

std::unique_ptr<TrackFilter> make_gaussian_sum_filter(const FilterSettings& settings);

}  // namespace dronetrack::fusion
