// Extra deterministic scenes for the simulator: an urban street with a hill, an indoor corridor and
// an open field. ROS-free.
#pragma once

#include "aloam_nodelet/sim/scene.h"

namespace aloam
{
namespace sim
{
/// Smooth ground height along x: flat (z = 0) before `start_x`, then a ramp of `grade` over
/// `length_m`, then flat again at grade * length_m. The two kinks are rounded over `blend_length_m`
/// (centered on the kinks; the slope follows a smoothstep there) so that the slope and its derivative
/// are continuous.
struct GroundProfile
{
  double start_x = 30.0;         // metres, start of the ramp (center of the first vertical curve)
  double length_m = 60.0;        // metres, horizontal length of the ramp (kink to kink)
  double grade = 0.04;           // rise over run of the ramp
  double blend_length_m = 10.0;  // metres, length of each vertical curve

  /// A profile with no hill (z = 0 everywhere).
  static GroundProfile flat();

  /// Ground height (metres) at x.
  double heightAt(double x) const;
  /// Slope dz/dx at x.
  double slopeAt(double x) const;
  /// Height at the top of the ramp.
  double rise() const { return grade * length_m; }
};

/// The street of Scene::urbanStreet(seed, length_m) on a ground following `profile`: the ground
/// plane is replaced by planar patches (vertical curves approximated by short chords) and every
/// other primitive is lifted by the lowest ground height under its footprint.
Scene urbanStreetWithHill(unsigned seed, double length_m, const GroundProfile& profile = GroundProfile());

/// Options of corridorScene. The corridor runs along +x from x = 0 to x = length_m, centered on y = 0.
struct CorridorOptions
{
  double length_m = 100.0;
  double width_m = 2.5;   // wall to wall
  double height_m = 3.0;  // floor (z = 0) to ceiling
  double wall_thickness_m = 0.4;
  double feature_spacing_m = 8.0;  // mean spacing of doors / recesses along each wall
  double spacing_jitter_m = 1.5;   // uniform jitter of that spacing
  double door_width_m = 1.0;
  double recess_depth_m = 0.3;   // doors are recessed this far behind the wall face
  double light_spacing_m = 4.0;  // ceiling lights (small boxes)
};

/// Indoor corridor with doors / recesses on alternating walls (deterministic for a seed).
Scene corridorScene(unsigned seed, const CorridorOptions& options = CorridorOptions());

/// Flat ground (z = 0) with very few objects (a few boxes, poles and a boulder) scattered along +x
/// between x = 20 and x = length_m, at least 8 m from the x axis.
Scene openFieldScene(unsigned seed, double length_m = 300.0);

}  // namespace sim
}  // namespace aloam
