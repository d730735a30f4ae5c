#include "fusion/assignment.hpp"

#include <algorithm>
#include <cmath>

namespace dronetrack::fusion {

void Assignment::solve(const std::vector<double>& cost, int rows, int cols,
                       std::vector<int>& row_to_col) {
  row_to_col.assign(static_cast<std::size_t>(std::max(rows, 0)), -1);
  if (rows <= 0 || cols <= 0) return;
  const int n = std::max(rows, cols);
  // Forbidden pairs cost more than any full set of allowed ones, so the optimum first maximises
  // the number of allowed pairs and only then minimises their cost. Padding is cheaper than
  // forbidden and costs the same everywhere.
  double largest = 0.0;
  for (double c : cost) {
    if (std::isfinite(c)) largest = std::max(largest, std::abs(c));
  }
  const double forbidden = (largest + 1.0) * (n + 1) * 2.0;
  const double padding = (largest + 1.0) * (n + 1);
  square_.assign(static_cast<std::size_t>(n) * n, padding);
  for (int r = 0; r < rows; ++r) {
    for (int c = 0; c < cols; ++c) {
      const double value = cost[static_cast<std::size_t>(r) * cols + c];
      square_[static_cast<std::size_t>(r) * n + c] = std::isfinite(value) ? value : forbidden;
    }
  }
  // e-maxx formulation, 1-based with a virtual column 0.
  const double infinity = std::numeric_limits<double>::infinity();
  u_.assign(n + 1, 0.0);
  v_.assign(n + 1, 0.0);
  match_.assign(n + 1, 0);
  way_.assign(n + 1, 0);
  for (int row = 1; row <= n; ++row) {
    match_[0] = row;
    int column0 = 0;
    min_to_.assign(n + 1, infinity);
    used_.assign(n + 1, 0);
    do {
      used_[column0] = 1;
      const int row0 = match_[column0];
      double delta = infinity;
      int column1 = 0;
      for (int column = 1; column <= n; ++column) {
        if (used_[column]) continue;
        const double reduced =
            square_[static_cast<std::size_t>(row0 - 1) * n + (column - 1)] - u_[row0] - v_[column];
        if (reduced < min_to_[column]) {
          min_to_[column] = reduced;
          way_[column] = column0;
        }
        if (min_to_[column] < delta) {
          delta = min_to_[column];
          column1 = column;
        }
      }
      for (int column = 0; column <= n; ++column) {
        if (used_[column]) {
          u_[match_[column]] += delta;
          v_[column] -= delta;
        } else {
          min_to_[column] -= delta;
        }
      }
      column0 = column1;
    } while (match_[column0] != 0);
    do {
      const int column1 = way_[column0];
      match_[column0] = match_[column1];
      column0 = column1;
    } while (column0 != 0);
  }
  for (int column = 1; column <= n; ++column) {
    const int row = match_[column] - 1;
    const int col = column - 1;
    if (row < rows && col < cols &&
        std::isfinite(cost[static_cast<std::size_t>(row) * cols + col])) {
      row_to_col[row] = col;
    }
  }
}

}  // namespace dronetrack::fusion
