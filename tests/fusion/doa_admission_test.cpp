// The engine's DOA checks on their own: known good and known bad DOAs against a two-array site.
#include "fusion/doa_admission.hpp"

#include <cmath>
#include <limits>
#include <numbers>

#include <gtest/gtest.h>

#include "fusion/state.hpp"
#include "scene.hpp"

namespace dronetrack::fusion::doa_admission_test {
namespace {

std::vector<doa::ArrayGeometry> two_arrays() {
  return {testing::tetrahedron("N1", {0, 0, 2}), testing::tetrahedron("N2", {20, 0, 2})};
}

doa::DoaMeasurement good_doa() {
  doa::DoaMeasurement m;
  m.array_id = "N2";
  m.array_index = 1;
  m.time_s = 1.0;
  m.direction = Eigen::Vector3d(1, 1, 1).normalized();
  m.azel_covariance_rad2 = MeasurementCovariance::Identity() * 1e-4;
  return m;
}

TEST(DoaAdmission, AGoodDoaIsAcceptedWithItsArraysIndex) {
  int index = -1;
  EXPECT_EQ(check_doa(good_doa(), two_arrays(), index), DoaVerdict::accepted);
  EXPECT_EQ(index, 1);
}

TEST(DoaAdmission, TheIdDecidesWhenTheIndexDisagrees) {
  doa::DoaMeasurement m = good_doa();
  m.array_index = 0;  // says N1, the id says N2
  int index = -1;
  EXPECT_EQ(check_doa(m, two_arrays(), index), DoaVerdict::accepted);
  EXPECT_EQ(index, 1);
  m.array_id = "N9";
  EXPECT_EQ(check_doa(m, two_arrays(), index), DoaVerdict::unknown_array);
  m.array_id.clear();
  m.array_index = 2;
  EXPECT_EQ(check_doa(m, two_arrays(), index), DoaVerdict::unknown_array);
}

TEST(DoaAdmission, BadValuesAreNamed) {
  int index = -1;
  doa::DoaMeasurement m = good_doa();
  m.time_s = std::numeric_limits<double>::quiet_NaN();
  EXPECT_EQ(check_doa(m, two_arrays(), index), DoaVerdict::non_finite);
  m = good_doa();
  m.direction *= 1.01;  // not a unit vector
  EXPECT_EQ(check_doa(m, two_arrays(), index), DoaVerdict::bad_direction);
  m = good_doa();
  m.azel_covariance_rad2(0, 1) = 1e-3;  // not symmetric
  EXPECT_EQ(check_doa(m, two_arrays(), index), DoaVerdict::bad_direction);
  m = good_doa();
  m.azel_covariance_rad2(1, 1) = -1e-4;  // not positive definite
  EXPECT_EQ(check_doa(m, two_arrays(), index), DoaVerdict::bad_direction);
  m = good_doa();
  m.source_index = 64;
  EXPECT_EQ(check_doa(m, two_arrays(), index), DoaVerdict::bad_direction);
}

TEST(DoaAdmission, ACone) {
  int index = -1;
  doa::DoaMeasurement m = good_doa();
  m.ambiguity = doa::DoaAmbiguity::cone;
  m.ambiguity_axis = Eigen::Vector3d::UnitX();
  m.cone_angle_rad = 1.0;
  m.cone_angle_variance_rad2 = 1e-3;
  EXPECT_EQ(check_doa(m, two_arrays(), index), DoaVerdict::accepted);
  m.cone_angle_rad = std::numbers::pi + 0.1;  // beyond [0, pi]
  EXPECT_EQ(check_doa(m, two_arrays(), index), DoaVerdict::bad_direction);
  m.cone_angle_rad = 1.0;
  m.cone_angle_variance_rad2 = 0.0;
  EXPECT_EQ(check_doa(m, two_arrays(), index), DoaVerdict::bad_direction);
  m.cone_angle_variance_rad2 = std::numeric_limits<double>::infinity();
  EXPECT_EQ(check_doa(m, two_arrays(), index), DoaVerdict::non_finite);
}

}  // namespace
}  // namespace dronetrack::fusion::doa_admission_test
