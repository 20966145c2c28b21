// Ply scattering by ray simulation (ray-wave model, main paper section 5.2, supplement section 1):
// narrow beams at incident angle theta_i and position h are traced through the procedural fibers
// of one ply (procedural_ply.h, Eq. 1-3), each fiber a smooth dielectric cylinder with the yarn's
// IOR. The outgoing directions are histogrammed per (theta_i, h) on a (theta_o, phi_o) grid,
// separately for first-surface reflection (f_refl) and all higher-order scattering (f_high).
//
// Ply space (supplement section 5): the ply runs along +z; the incident direction (towards the
// light) is omega_i = (0, cos theta_i, sin theta_i); h in [-1, 1] is the beam's offset along +x in
// units of the ply radius; theta_o = asin(omega_o.z), phi_o = atan2(omega_o.y, omega_o.x). f is a
// density over solid angle: the fraction of the beam's power per steradian.
//
// Choices where the text is silent (each stated here once):
//  * Fibers are polylines of straight cylinder segments (kSegmentsPerPitch per twist pitch; the
//    chord error at the ply radius is below 1e-3 fiber radii), found through a uniform grid. The pattern is periodic in z over
//    the smallest multiple of the pitch that holds whole migration cycles (up to 8 pitches),
//    so beams never run off the end of the ply.
//  * A ray inside a fiber only sees that fiber's (locally straight) surface: fibers that overlap
//    in space are treated as if the one entered first owned the overlap.
//  * The beam is uniform over z in one period and over x in [h - w, h + w] R_ply with
//    w = beam_halfwidth (default: half the h spacing), so neighbouring slices tile the ply; h = +-1 is the
//    ply's silhouette (the outermost fiber centre plus a fiber radius).
//  * f_refl is the power that leaves after a single external reflection at the first fiber the
//    beam meets; everything else that leaves after touching a fiber is f_high. Rays that miss every
//    fiber are `unscattered` (a forward delta, left to the transmission model), rays still inside
//    after max_events interactions are `truncated`. Flyaways are not simulated.
//  * Sampling: at the first hit both the reflected (weight F) and refracted (1 - F) branches are
//    followed; afterwards each interface picks one branch with probability F (Russian roulette), so
//    every ray ends with exactly its weight in one category and energy is conserved exactly.
//  * Absorption: sigma is in 1/mm of path inside fibers. Each path's total in-fiber length l is
//    kept, so one simulation yields f_high for every sigma_k (weight exp(-sigma_k l)).
//  * Determinism: every ray's random numbers are a pure function of (seed, slice, ray), and a
//    slice is accumulated in ray order on one thread, so results do not depend on the thread count.
#pragma once
#include <cstdint>
#include <vector>

#include "loom/procedural_ply.h"
#include "loom/spec.h"

namespace loom {

struct PlySimSettings {
  int theta_i_count = 9;  ///< odd (block fitting, Eq. S.3), samples over [-theta_i_max, theta_i_max]
  int h_count = 9;        ///< odd, samples over [-1, 1]
  double theta_i_max_deg = 80;  ///< beams closer to the ply axis are clamped to this angle
  int theta_o_count = 32;       ///< bins over [-90, 90] degrees
  int phi_o_count = 64;         ///< bins over [-180, 180) degrees
  int rays_per_slice = 20000;
  std::vector<double> sigmas = {0, 5, 20, 80};  ///< absorption levels (1/mm), sigmas[0] = 0
  double beam_halfwidth = -1;   ///< in units of R_ply; < 0: half the h spacing
  int max_events = 64;          ///< interactions before a path counts as truncated
  uint64_t seed = 1;
};

/// Grid sizes, ray counts and absorption levels of a quality preset.
PlySimSettings ply_sim_settings(Quality q);

/// Energy fractions of one (theta_i, h) slice at one absorption level.
struct PlySimEnergy {
  double reflected = 0, higher_order = 0, absorbed = 0, unscattered = 0, truncated = 0;
};

struct PlySimSlice {
  double theta_i = 0, h = 0;                 ///< radians, normalised offset
  std::vector<PlySimEnergy> energy;           ///< per sigma level
  std::vector<float> refl;                    ///< theta_o_count x phi_o_count densities
  std::vector<float> high;                    ///< sigma levels x theta_o_count x phi_o_count
};

struct PlySimResult {
  PlySimSettings settings;
  std::vector<double> theta_i, h;  ///< the grids (radians, normalised)
  std::vector<PlySimSlice> slices; ///< theta_i-major: slices[m * h_count + n]
  uint64_t rays = 0;
  double silhouette_radius_um = 0;  ///< the length h = 1 stands for
  const PlySimSlice& slice(int m, int n) const { return slices[size_t(m) * h.size() + size_t(n)]; }
};

/// Solid angle of outgoing bin (t, p) on the settings' grid.
double ply_sim_bin_solid_angle(const PlySimSettings& s, int t);
/// Centre direction (ply space) of outgoing bin (t, p).
Vec3d ply_sim_bin_direction(const PlySimSettings& s, int t, int p);
/// Bin of an outgoing direction (unit vector, ply space).
void ply_sim_bin_of(const PlySimSettings& s, const Vec3d& w, int& t, int& p);

/// The ply geometry the simulation traces: straight cylinder segments, periodic in z.
class PlyGeometry {
 public:
  PlyGeometry(const PlyParams& p, const std::vector<Fiber>& fibers);
  struct Hit {
    double t = 0;
    int segment = -1;
    double z_offset = 0;  ///< the periodic image of the segment that was hit
    Vec3d normal;         ///< outward, unit
  };
  /// Nearest entry into any fiber along o + t d (t > t_min); false if the ray leaves the ply.
  bool intersect_entry(const Vec3d& o, const Vec3d& d, double t_min, Hit& hit) const;
  /// Exit from inside segment `segment`'s (infinite, locally straight) cylinder along o + t d.
  bool intersect_exit(int segment, double z_offset, const Vec3d& o, const Vec3d& d,
                      Hit& hit) const;
  double period() const { return period_; }
  double bound_radius() const { return bound_; }

 private:
  struct Segment {
    Vec3d p0, axis;  ///< start and unit axis
    double len = 0;
  };
  std::vector<Segment> seg_;
  // Uniform grid over [-bound, bound]^2 x [0, period) (periodic in z), compressed rows: the
  // segments whose r-expanded bounding box overlaps cell c are cell_seg_[cell_start_[c] ..
  // cell_start_[c + 1]). Rays walk it with a 3D DDA (Amanatides and Woo 1987).
  std::vector<int> cell_start_, cell_seg_;
  int nx_ = 1, nz_ = 1;
  double cell_xy_ = 1, cell_z_ = 1;
  double period_ = 0, bound_ = 0, r_ = 0;
  int cell_index(int ix, int iy, int iz_wrapped) const { return (iz_wrapped * nx_ + iy) * nx_ + ix; }
};

inline constexpr int kSegmentsPerPitch = 96;

/// Simulate every (theta_i, h) slice of the settings' grid (TBB over slices).
PlySimResult simulate_ply_scattering(const PlyParams& p, double ior, const PlySimSettings& s);
/// Simulate one slice at arbitrary (theta_i, h) (single thread); slice_index seeds it.
PlySimSlice simulate_ply_slice(const PlyGeometry& g, double ior, const PlySimSettings& s,
                               double theta_i, double h, uint64_t slice_index);

}  // namespace loom
