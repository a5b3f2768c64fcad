// Looping scenes and path-following motions for the simulator (loop-closure tests): a city grid of blocks
// with streets between them (optionally every block identical), a ring corridor round a building floor,
// a closed or open path with rounded corners that a car or a walker follows, and the ground-truth revisits
// of a trajectory. ROS-free and deterministic.
#pragma once

#include <vector>

#include <Eigen/Geometry>

#include "aloam_nodelet/sim/raycaster.h"
#include "aloam_nodelet/sim/scene.h"

namespace aloam
{
namespace sim
{
/// A polyline through `waypoints` whose corners are rounded: at every corner the heading turns by the
/// corner's angle over `corner_length_m` of path, following a smoothstep in distance (the yaw rate rises
/// and falls smoothly), and the turn starts and ends on the two straight legs. Collinear waypoints make no
/// turn. A closed path repeats after length(); an open one goes on straight beyond both ends.
class RoundedPath
{
public:
  /// Throws std::invalid_argument for fewer than two waypoints, a U-turn or legs too short for their turns.
  RoundedPath(const std::vector<Eigen::Vector2d>& waypoints, bool closed, double corner_length_m);

  /// One lap of a closed path; the whole path (first to last waypoint) of an open one.
  double length() const { return length_; }
  bool closed() const { return closed_; }
  /// Point `s` metres along the path (s = 0 at the first waypoint).
  Eigen::Vector2d position(double s) const;
  /// Heading (rad), continuous in s (a closed path gains its net turn every lap).
  double heading(double s) const;
  /// Signed curvature (1/m, positive to the left).
  double curvature(double s) const;

private:
  struct Piece
  {
    double s0 = 0.0;      // start along the path
    double length = 0.0;  // metres
    double heading0 = 0.0;
    double turn = 0.0;  // heading change over the piece; 0 for a straight
    Eigen::Vector2d start = Eigen::Vector2d::Zero();
    std::vector<Eigen::Vector2d> table;  // turn: positions relative to `start` at equal steps
  };
  const Piece& pieceAt(double s, double* local, double* laps) const;

  bool closed_ = true;
  double length_ = 0.0;
  double net_turn_ = 0.0;
  std::vector<Piece> pieces_;
};

/// A sensor following a RoundedPath at constant speed: heading along the path tangent, `height_m` above
/// flat ground (z = 0), optionally offset sideways from the path, with hand-held bobbing, roll sway and
/// yaw sway (all zero for a car).
struct PathFollowOptions
{
  std::vector<Eigen::Vector2d> waypoints;
  bool closed = true;
  double corner_length_m = 18.0;
  double speed = 8.0;             // m/s along the path
  double start_distance_m = 0.0;  // along the path at t = 0
  double height_m = 1.8;
  double lateral_offset_m = 0.0;  // to the left of the path; negative: to the right
  double bob_amplitude_m = 0.0;
  double bob_frequency_hz = 2.0;
  double roll_amplitude_rad = 0.0;  // at half the bobbing frequency
  double yaw_sway_rad = 0.0;        // at half the bobbing frequency, a quarter period after the roll
};

PoseFunction pathFollow(const PathFollowOptions& options);

/// A grid of city blocks with streets between them. Street centerlines run north-south at every
/// `street_x` and east-west at every `street_y` (ascending); a block fills each cell between neighbouring
/// streets, and with outer_block_m > 0 a block of that depth lies beyond the outermost streets too. Every
/// block edge that faces a street gets the frontage of Scene::urbanStreet (sidewalk, buildings with
/// stepped facades and gaps, poles, trees) drawn from `facade`, and parked cars along its kerb, none within
/// kNoParkingM of a corner. Ground at z = 0 reaches ground_margin_m beyond everything.
struct CityGridOptions
{
  static constexpr double kNoParkingM = 10.0;

  std::vector<double> street_x = { 0.0, 100.0 };
  std::vector<double> street_y = { 0.0, 80.0 };
  double street_width_m = 14.0;  // kerb to kerb
  double outer_block_m = 40.0;
  double ground_margin_m = 150.0;
  /// Every block gets the same layout (one seed for all): with equally spaced streets the blocks are
  /// copies of one another shifted by the spacing.
  bool identical_blocks = false;
  /// Building, pole and tree ranges of the frontage (its length, street width and margins are set per edge);
  /// car_probability is the chance that a parking slot is taken.
  UrbanStreetOptions facade;
};

Scene cityGridScene(unsigned seed, const CityGridOptions& options);

/// A floor of a building: a ring corridor round a central core. The core spans |x| <= core_x_m / 2,
/// |y| <= core_y_m / 2 and the corridor is width_m wide around it, between the floor (z = 0) and the
/// ceiling. Along both walls: door recesses, niches and open doors into rooms (behind the outer wall the
/// rooms are room_depth_m deep, in the core as deep as it allows), every feature_spacing_m or so, and
/// ceiling lights along the centerline.
struct RingFloorOptions
{
  double core_x_m = 24.0;
  double core_y_m = 14.0;
  double width_m = 2.4;
  double height_m = 3.0;
  double wall_thickness_m = 0.25;
  double room_depth_m = 4.0;
  double feature_spacing_m = 6.0;  // mean centre-to-centre distance of features along a wall
  double door_width_m = 1.0;
  double recess_depth_m = 0.3;
  double room_probability = 0.3;   // an open door into a room
  double niche_probability = 0.2;  // a shallow full-height niche; the rest are door recesses
  double light_spacing_m = 4.0;    // 0: none
};

Scene ringFloorScene(unsigned seed, const RingFloorOptions& options);
/// The corridor's centerline as closed waypoints, counterclockwise from the middle of its south side.
std::vector<Eigen::Vector2d> ringFloorCenterline(const RingFloorOptions& options);

/// A true revisit: the sensor at `later_s` is within `distance_m` of where it was at `earlier_s`.
struct Revisit
{
  double earlier_s = 0.0;
  double later_s = 0.0;
  double distance_m = 0.0;
};

/// The true revisits of a ground-truth trajectory (poses[i] at times[i]): for every sample, the nearest
/// earlier sample more than `min_gap_s` before it, if that one is within `radius_m` (sensor positions).
/// One pair per later sample, ordered by the later time. Throws std::invalid_argument if the sizes differ.
std::vector<Revisit> trueRevisits(const std::vector<double>& times, const std::vector<Eigen::Isometry3d>& poses,
                                  double radius_m = 2.0, double min_gap_s = 30.0);
/// The same, sampling `pose_at` every `step_s` over [0, duration_s].
std::vector<Revisit> trueRevisits(const PoseFunction& pose_at, double duration_s, double step_s, double radius_m = 2.0,
                                  double min_gap_s = 30.0);
/// Whether a loop between the poses at `t_a` and `t_b` is a true revisit (positions within `radius_m`).
bool isTrueRevisit(const PoseFunction& pose_at, double t_a, double t_b, double radius_m = 2.0);

}  // namespace sim
}  // namespace aloam
