#pragma once
// The outlier mixture's e estimated from the data, one estimate per array (issue 17,
// fusion.adaptive_outlier_probability; docs/fusion.md "Estimating e"). Outliers are a property of
// an array's acoustics (reflections, wind, a second source captured for a frame), not of a track.
// Under the mixture a gated DOA's likelihood is proportional to 1 - e + e g, g the uniform part's
// density over the Gaussian part's at its d^2 (DoaLikelihood::outlier_density_ratio): g is all a
// DOA says about e. e is the maximum of the posterior over the last window_doas DOAs with a Beta
// prior of prior_doas pseudo-DOAs at prior_share:
//   sum_k ln(1 - e + e g_k) + prior_doas (prior_share ln e + (1 - prior_share) ln(1 - e)),
// concave in e, so a few Newton steps from the previous estimate find it after each frame. With no
// data it is prior_share; it never reaches 0 or 1 while prior_share is inside (0, 1). Not EM's
// e <- mean(1 - beta): near e = 0 the EM map is almost the identity (docs/fusion.md), so EM would
// creep over hundreds of DOAs where the posterior's maximum moves as soon as the data do.
// The ring of g is allocated once; add() and refresh() allocate nothing.
#include <vector>

namespace dronetrack::fusion {

class OutlierShareEstimate {
 public:
  // prior_share in [0, 1), prior_doas >= 0, window_doas >= 1 (validated in config/).
  OutlierShareEstimate(double prior_share, double prior_doas, int window_doas);

  // The current estimate of e: the share of gated DOAs that are not the track's.
  double share() const { return share_; }
  // One gated DOA's g (> 0); the oldest leaves the window once it is full.
  void add(double density_ratio);
  // Moves share() to the posterior's maximum over the window (Newton, safeguarded).
  void refresh();
  int count() const { return count_; }

 private:
  // d/de and d2/de2 of the log posterior at e.
  void derivatives(double e, double& slope, double& curvature) const;

  double prior_outliers_;  // prior_doas * prior_share
  double prior_inliers_;   // prior_doas * (1 - prior_share)
  std::vector<double> ratio_;
  int next_ = 0;
  int count_ = 0;
  double share_;
};

}  // namespace dronetrack::fusion
