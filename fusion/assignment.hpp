#pragma once
// Optimal assignment (Hungarian method with potentials, O(n^2 m)) for global-nearest-neighbour
// association of DOAs to tracks, and of tracks to truth in the evaluation. Costs of +infinity
// mark forbidden pairs (outside the gate); they are never assigned. The solver keeps its
// workspace between calls so the per-frame association allocates nothing once warm.
#include <limits>
#include <vector>

namespace dronetrack::fusion {

inline constexpr double kForbidden = std::numeric_limits<double>::infinity();

class Assignment {
 public:
  // cost is rows x cols, row-major. Fills row_to_col (size rows, -1 = unassigned) so that the
  // sum of assigned costs is minimal among assignments with the largest number of allowed pairs.
  void solve(const std::vector<double>& cost, int rows, int cols, std::vector<int>& row_to_col);

 private:
  std::vector<double> square_;
  std::vector<double> u_, v_, min_to_;
  std::vector<int> match_, way_;
  std::vector<char> used_;
};

}  // namespace dronetrack::fusion
