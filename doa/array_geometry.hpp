#pragma once
// Where an array is and where its microphones are. Mic positions are given in the array frame;
// the array frame is turned by yaw about +z (counter-clockwise), then pitch about the new +y,
// then roll about the new +x (array_to_site = Rz(yaw) Ry(pitch) Rx(roll)), and translated to
// position_m to give the site frame (x east, y north, z up; SPEC section 2).
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace dronetrack::doa {

struct ArrayGeometry {
  std::string id;
  Eigen::Vector3d position_m = Eigen::Vector3d::Zero();  // site frame
  double yaw_deg = 0.0;
  double pitch_deg = 0.0;  // a tilted mast or a vehicle on a slope; 0 for a level array
  double roll_deg = 0.0;
  std::vector<Eigen::Vector3d> mics_m;  // array frame, one per channel after channel_map
  // 1-sigma uncertainty of each mic coordinate; feeds the DOA's measurement noise.
  double mic_position_std_m = 0.0;
  // What a site calibration measured (docs/calibration.md). Per mic (empty: none): how late its
  // channel hears (s) and how loud (dB), both undone on its spectrum before the correlations;
  // and how far the node's clock runs ahead of the site's (s), taken off every DOA's time.
  std::vector<double> channel_delay_s{};
  std::vector<double> channel_gain_db{};
  double clock_offset_s = 0.0;

  Eigen::Matrix3d array_to_site() const;              // rotation only
  Eigen::Vector3d mic_site_m(std::size_t mic) const;  // absolute site position of a mic
  // The acoustic centre: the mic centroid in the site frame. DOAs point from here.
  Eigen::Vector3d centre_site_m() const;
  std::size_t mic_count() const { return mics_m.size(); }
};

// Rz(yaw) Ry(pitch) Rx(roll): the rotation taking array-frame vectors to the site frame.
Eigen::Matrix3d attitude_to_site(double yaw_deg, double pitch_deg, double roll_deg);
// (yaw, pitch, roll) in degrees of a rotation: the inverse of attitude_to_site with pitch in
// [-90, 90] (yaw and roll in (-180, 180]).
Eigen::Vector3d attitude_deg_of(const Eigen::Quaterniond& array_to_site);

// Azimuth = atan2(u_y, u_x), elevation = asin(u_z), degrees (SPEC section 2).
double azimuth_deg(const Eigen::Vector3d& unit_direction);
double elevation_deg(const Eigen::Vector3d& unit_direction);
Eigen::Vector3d direction_from_azel_deg(double azimuth_deg, double elevation_deg);
// Wraps an angle difference to (-180, 180]. The one place angles wrap.
double wrap_deg_180(double angle_deg);
double wrap_rad_pi(double angle_rad);
// Great-circle angle between two directions, degrees, in [0, 180].
double angle_between_deg(const Eigen::Vector3d& a, const Eigen::Vector3d& b);

}  // namespace dronetrack::doa
