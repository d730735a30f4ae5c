#pragma once
// What a filter predicts for one DOA before it commits it: the tracker gates and assigns on it, the
// DOA likelihood (doa_likelihood.hpp) weighs the DOA by it, and the filter then updates with it.
#include <optional>

#include "fusion/measurement_model.hpp"
#include "fusion/state.hpp"

namespace dronetrack::fusion {

struct Innovation {
  Measurement predicted = Measurement::Zero();                           // z_hat
  MeasurementCovariance covariance = MeasurementCovariance::Identity();  // S = ... + R
  CrossCovariance cross = CrossCovariance::Zero();                       // P_xz
  MeasurementCovariance noise = MeasurementCovariance::Identity();       // R
  const DoaMeasurementModel* model = nullptr;
  // The outlier mixture's e for this DOA when the tracker estimates it per array
  // (fusion.adaptive_outlier_probability, outlier_share.hpp); unset: the law's configured e.
  // A filter's innovation() leaves it unset: the tracker sets it for the DOA it gates and updates.
  std::optional<double> outlier_probability;
  // z - predicted in the model's space (wrapped azimuth, or the plain cone angle); azel when no
  // model is set.
  Measurement residual(const Measurement& z) const;
  // Degrees of freedom of the measurement (1: cone, 2: a direction).
  int dimension() const { return model != nullptr ? model->dimension() : kMeasurementSize; }
  // Squared Mahalanobis distance of a measurement z under this innovation.
  double mahalanobis2(const Measurement& z) const;
};

}  // namespace dronetrack::fusion
