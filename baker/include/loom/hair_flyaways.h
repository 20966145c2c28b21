// Realization-free hair flyaways (Luan, Zhao, Bala 2017, section 4.4.2, Algorithm 3): the hairs
// of a ply whose z extent holds a given z, found without generating or storing any hair, by
// descending an implicit quadtree over the hairs' (z1, z2) end points (after Jakob et al. 2014)
// that splits a node's hair count among its four children by a multinomial draw.
//
// The hair process is the one of make_hair (procedural_ply.h): z1 uniform on [0, length), the
// length z2 - z1 uniform on [hair_length_min, hair_length_max], R and theta as in make_hair, the
// count Poisson with the ply's density (ply_hair_count). Its hairs are other samples of that
// process than make_hair's, so a realization to compare with is the same tree descended
// everywhere (all_hairs_realization_free).
//
// Choices where the text is silent:
// - the root domain is [0, length] x [0, length + hair_length_max];
// - a node's random numbers come from a generator seeded by (yarn, ply, node path), so a node
//   draws the same split whenever it is visited: consistent seeding (section 5.3);
// - the multinomial is drawn as three nested binomials (std::binomial_distribution: the same
//   hairs on every run with one C++ standard library, not across libraries);
// - below depth 40 a node's remaining hairs are drawn one by one (never reached in practice:
//   each split quarters the domain);
// - a leaf's hair is drawn exactly from the process restricted to the leaf: z1 by rejection
//   against its marginal (a trapezoid, so at least half the proposals are kept), the length
//   uniform on what the leaf leaves, then R and theta.
#pragma once
#include <cstdint>
#include <vector>

#include "loom/procedural_ply.h"

namespace loom {

struct HairFlyaway {
  uint64_t id = 0;  ///< a 64-bit hash of the leaf's path: unique within the ply but for collisions
                    ///< of probability ~n^2 / 2^65
  Hair hair;
};

/// P[z1 in [a, b] and z2 in [c, d]] under the hair process over a ply of this length, in closed
/// form (the integral of a clamped linear function).
double hair_extent_probability(const PlyParams& p, double length, double a, double b, double c,
                               double d);

/// Algorithm 3: the hairs of ply `ply` of yarn `yarn` with z in [z1 - margin, z2 + margin],
/// appended to `out`.
void active_hairs(const PlyParams& p, uint32_t yarn, uint32_t ply, double length, double z,
                  double margin, std::vector<HairFlyaway>& out);

/// Every hair of the same implicit tree: its full realization.
std::vector<HairFlyaway> all_hairs_realization_free(const PlyParams& p, uint32_t yarn,
                                                    uint32_t ply, double length);

}  // namespace loom
