#pragma once
// Direction sectors over the sphere: the cells of a Fibonacci lattice (near-equal areas; 32
// cells are ~36 deg across). Evidence gathered from directions is grouped by sector so that one
// long look from one direction counts as one look, not as its frames (doa/channel_delay_fit,
// fusion/array_mirror_check). Sized in the constructor; nearest() allocates nothing.
#include <cmath>
#include <numbers>
#include <vector>

#include <Eigen/Core>

namespace dronetrack::doa {

class DirectionSectors {
 public:
  explicit DirectionSectors(int count) {
    const double golden_angle = std::numbers::pi * (3.0 - std::sqrt(5.0));
    centres_.reserve(static_cast<std::size_t>(count));
    for (int s = 0; s < count; ++s) {
      const double z = 1.0 - (2.0 * s + 1.0) / count;
      const double radius = std::sqrt(1.0 - z * z);
      centres_.emplace_back(radius * std::cos(golden_angle * s),
                            radius * std::sin(golden_angle * s), z);
    }
  }
  int count() const { return static_cast<int>(centres_.size()); }
  // The sector whose centre is closest to `direction` (unit vector).
  int nearest(const Eigen::Vector3d& direction) const {
    int best = 0;
    double best_dot = -2.0;
    for (std::size_t s = 0; s < centres_.size(); ++s) {
      const double dot = centres_[s].dot(direction);
      if (dot > best_dot) {
        best_dot = dot;
        best = static_cast<int>(s);
      }
    }
    return best;
  }

 private:
  std::vector<Eigen::Vector3d> centres_;
};

}  // namespace dronetrack::doa
