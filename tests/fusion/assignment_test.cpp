#include "fusion/assignment.hpp"

#include <algorithm>
#include <numeric>
#include <random>

#include <functional>

#include <gtest/gtest.h>

namespace dronetrack::fusion::assignment_test {
namespace {

// Brute force over all injective maps rows -> cols (or -1), maximising the number of allowed
// pairs first, then minimising cost.
std::pair<int, double> brute_force(const std::vector<double>& cost, int rows, int cols) {
  std::pair<int, double> best{-1, 0.0};
  std::vector<int> choice(rows, -1);
  std::vector<char> used(cols, 0);
  std::function<void(int, int, double)> recurse = [&](int row, int pairs, double total) {
    if (row == rows) {
      if (pairs > best.first || (pairs == best.first && total < best.second - 1e-12)) {
        best = {pairs, total};
      }
      return;
    }
    recurse(row + 1, pairs, total);
    for (int c = 0; c < cols; ++c) {
      const double value = cost[row * cols + c];
      if (used[c] || !std::isfinite(value)) continue;
      used[c] = 1;
      recurse(row + 1, pairs + 1, total + value);
      used[c] = 0;
    }
  };
  recurse(0, 0, 0.0);
  return best;
}

TEST(Assignment, MatchesBruteForceWithForbiddenPairs) {
  std::mt19937_64 random(1);
  std::uniform_real_distribution<double> uniform(0.0, 10.0);
  Assignment solver;
  std::vector<int> row_to_col;
  for (int trial = 0; trial < 300; ++trial) {
    const int rows = 1 + trial % 5;
    const int cols = 1 + (trial / 5) % 5;
    std::vector<double> cost(rows * cols);
    for (double& c : cost) c = uniform(random) < 3.0 ? kForbidden : uniform(random);
    solver.solve(cost, rows, cols, row_to_col);
    int pairs = 0;
    double total = 0.0;
    std::vector<int> seen;
    for (int r = 0; r < rows; ++r) {
      if (row_to_col[r] < 0) continue;
      ASSERT_TRUE(std::isfinite(cost[r * cols + row_to_col[r]]));
      seen.push_back(row_to_col[r]);
      ++pairs;
      total += cost[r * cols + row_to_col[r]];
    }
    std::sort(seen.begin(), seen.end());
    EXPECT_EQ(std::adjacent_find(seen.begin(), seen.end()), seen.end());
    const auto best = brute_force(cost, rows, cols);
    EXPECT_EQ(pairs, best.first) << "trial " << trial;
    EXPECT_NEAR(total, best.second, 1e-9) << "trial " << trial;
  }
}

}  // namespace
}  // namespace dronetrack::fusion::assignment_test
