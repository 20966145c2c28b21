#include "loom/hair_flyaways.h"

#include <algorithm>
#include <cmath>
#include <random>

namespace loom {
namespace {

constexpr int kMaxDepth = 40;
constexpr uint64_t kRoot = 0x48414952u;  // "HAIR"

uint64_t mix(uint64_t x) {  // SplitMix64's finaliser
  x += 0x9E3779B97F4A7C15ull;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
  return x ^ (x >> 31);
}

uint64_t node_seed(uint32_t yarn, uint32_t ply, uint64_t code, uint64_t salt) {
  return mix(mix(mix(code) ^ (uint64_t(yarn) << 32 | ply)) ^ salt);
}

double uniform(std::mt19937_64& g) { return double(g() >> 11) * (1.0 / 9007199254740992.0); }

struct Process {
  double L, lmin, lmax;
  explicit Process(const PlyParams& p, double length)
      : L(length), lmin(p.hair_length_min), lmax(std::max(p.hair_length_max, p.hair_length_min + 1e-6)) {}
  double C(double x) const { return std::clamp(x, lmin, lmax); }
  /// G(x) = int_0^x C(t) dt.
  double G(double x) const {
    if (x <= lmin) return lmin * x;
    if (x <= lmax) return lmin * lmin + 0.5 * (x * x - lmin * lmin);
    return lmin * lmin + 0.5 * (lmax * lmax - lmin * lmin) + lmax * (x - lmax);
  }
  /// The z1 marginal on [c, d] for z2, unnormalised: |[c - z1, d - z1] ^ [lmin, lmax]|.
  double g(double z1, double c, double d) const { return C(d - z1) - C(c - z1); }
  double probability(double a, double b, double c, double d) const {
    a = std::max(a, 0.0), b = std::min(b, L);
    if (!(b > a) || !(d > c) || L <= 0) return 0;
    double I = (G(d - a) - G(d - b)) - (G(c - a) - G(c - b));
    return std::max(0.0, I / (L * (lmax - lmin)));
  }
};

struct Node {
  double a, b, c, d;  ///< z1 in [a, b], z2 in [c, d]
};

/// The hair `i` of a leaf: the process restricted to the leaf's domain.
bool draw_leaf_hair(const PlyParams& p, const Process& P, const Node& n, uint32_t yarn,
                    uint32_t ply, uint64_t code, uint32_t i, Hair& h) {
  std::mt19937_64 g(node_seed(yarn, ply, code, 0x1EAF0000ull + i));
  double lo = std::max({n.a, n.c - P.lmax, 0.0}), hi = std::min({n.b, n.d - P.lmin, P.L});
  if (!(hi > lo)) return false;
  double gmax = 0;
  for (double x : {lo, hi, n.d - P.lmax, n.d - P.lmin, n.c - P.lmax, n.c - P.lmin})
    gmax = std::max(gmax, P.g(std::clamp(x, lo, hi), n.c, n.d));
  if (!(gmax > 0)) return false;
  double z1 = lo;
  for (int t = 0; t < 256; ++t) {  // the marginal is a trapezoid: half or more accepted
    z1 = lo + (hi - lo) * uniform(g);
    if (uniform(g) * gmax <= P.g(z1, n.c, n.d)) break;
  }
  double l0 = std::max(n.c - z1, P.lmin), l1 = std::min(n.d - z1, P.lmax);
  h.z1 = z1;
  h.z2 = z1 + l0 + std::max(l1 - l0, 0.0) * uniform(g);
  draw_hair_shape(p, h, [&] { return uniform(g); });  // R and theta as make_hair draws them
  return true;
}

/// Algorithm 3's ACTIVEFIBERS; `all` visits every node (the full realization).
void descend(const PlyParams& p, const Process& P, uint32_t yarn, uint32_t ply, const Node& n,
             int count, uint64_t code, int depth, double z, double margin, bool all,
             std::vector<HairFlyaway>& out) {
  if (count <= 0) return;
  if (!all && (n.a > z + margin || n.d < z - margin)) return;  // Omega ^ D(z) empty
  if (count == 1 || depth >= kMaxDepth) {
    for (int i = 0; i < count; ++i) {
      Hair h;
      if (!draw_leaf_hair(p, P, n, yarn, ply, code, uint32_t(i), h)) continue;
      if (all || (z >= h.z1 - margin && z <= h.z2 + margin))
        out.push_back({mix(code ^ (uint64_t(i) << 48)), h});
    }
    return;
  }
  double mx = 0.5 * (n.a + n.b), my = 0.5 * (n.c + n.d);
  Node kids[4] = {{n.a, mx, n.c, my}, {mx, n.b, n.c, my}, {n.a, mx, my, n.d}, {mx, n.b, my, n.d}};
  double pk[4], total = 0;
  for (int k = 0; k < 4; ++k) total += pk[k] = P.probability(kids[k].a, kids[k].b, kids[k].c, kids[k].d);
  if (!(total > 0)) return;
  // The multinomial as nested binomials, from the node's own generator.
  std::mt19937_64 g(node_seed(yarn, ply, code, 0x5B117ull));
  int left = count, nk[4] = {0, 0, 0, 0};
  double rest = total;
  for (int k = 0; k < 3 && left > 0; ++k) {
    double q = rest > 0 ? std::clamp(pk[k] / rest, 0.0, 1.0) : 0.0;
    nk[k] = std::binomial_distribution<int>(left, q)(g);
    left -= nk[k];
    rest -= pk[k];
  }
  nk[3] = left;
  for (int k = 0; k < 4; ++k)
    descend(p, P, yarn, ply, kids[k], nk[k], mix(code * 4 + uint64_t(k) + 1), depth + 1, z,
            margin, all, out);
}

}  // namespace

double hair_extent_probability(const PlyParams& p, double length, double a, double b, double c,
                               double d) {
  return Process(p, length).probability(a, b, c, d);
}

void active_hairs(const PlyParams& p, uint32_t yarn, uint32_t ply, double length, double z,
                  double margin, std::vector<HairFlyaway>& out) {
  HairCount hc = ply_hair_count(p, yarn, ply, length);
  Process P(p, length);
  descend(p, P, yarn, ply, {0, length, 0, length + P.lmax}, int(hc.count), kRoot, 0, z, margin,
          false, out);
}

std::vector<HairFlyaway> all_hairs_realization_free(const PlyParams& p, uint32_t yarn,
                                                    uint32_t ply, double length) {
  std::vector<HairFlyaway> out;
  HairCount hc = ply_hair_count(p, yarn, ply, length);
  Process P(p, length);
  descend(p, P, yarn, ply, {0, length, 0, length + P.lmax}, int(hc.count), kRoot, 0, 0, 0, true,
          out);
  return out;
}

}  // namespace loom
