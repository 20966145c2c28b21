#include "loom/closure_fit.h"

#include <ceres/ceres.h>

#include <algorithm>
#include <cmath>
#include <vector>

namespace loom {

using namespace shading;

SpecularClosureSet::SpecularClosureSet(const SpecularClosures& p, vec3 V, vec3 t)
    : p_(p),
      ggx_(cycles::ensure_valid_specular_reflection(vec3(0, 0, 1), V, surface_glossy_normal(t)),
           t, p.ggx_ax, p.ggx_ay, vec3(0, 0, 1), V),
      ht_(vec3(0, 0, 1), t, p.ht_r1, p.ht_r2, 0, V, true) {}

float SpecularClosureSet::eval(vec3 L) const {
  if (L.z > 0) return p_.ggx_w > 0 ? p_.ggx_w * ggx_.eval(L) : 0.0f;
  float f = p_.tl_w * cycles::translucent_eval(vec3(0, 0, 1), L, vec3(0, 0, 1));
  if (p_.ht_w > 0) f += p_.ht_w * ht_.eval(L);
  return f;
}

namespace {

/// The quadrature of one hemisphere: directions, solid angles, the model's f <L.n_s>.
struct Samples {
  std::vector<vec3> L;
  std::vector<double> dw, model;
  double albedo = 0;
};

double relative_l1(const Samples& s, const SpecularClosures& p, vec3 V, vec3 t) {
  if (s.albedo <= 0) return 0;
  const SpecularClosureSet c(p, V, t);
  double num = 0;
  for (size_t k = 0; k < s.L.size(); ++k) num += std::fabs(c.eval(s.L[k]) - s.model[k]) * s.dw[k];
  return num / s.albedo;
}

/// Scales one hemisphere's weights (reflection or transmission) so that its closures carry the
/// model's albedo A there: the energy the closures reflect and transmit is the model's, for
/// every cell.
void rescale_to_model(double A, bool refl, SpecularClosures& p, vec3 V, vec3 t, float a,
                      const ClosureFitOptions& o) {
  SpecularClosures only = p;  // the other hemisphere's closures need no quadrature
  if (refl)
    only.ht_w = only.tl_w = 0;
  else
    only.ggx_w = 0;
  const SpecularEnergies e = specular_closure_energies(only, V, t, a, o.judge_n, o.judge_m);
  const double have = refl ? e.reflect : e.transmit;
  const float k = have > 1e-12 ? float(A / have) : 0.0f;
  if (refl)
    p.ggx_w *= k;
  else
    p.ht_w *= k, p.tl_w *= k;
}

/// Which entries of SpecularClosures a hemisphere's fit moves, and their bounds.
struct Param {
  float SpecularClosures::*field;
  double lo, hi;
};

/// Residuals sqrt(dw) e / sqrt(sqrt(e^2 + eps^2) + eps), e = (closures - model) / albedo: their
/// squares sum to the Charbonnier penalty of the relative L1 (see closure_fit.h).
struct HemisphereCost {
  const Samples& s;
  const std::vector<Param>& params;
  SpecularClosures base;
  vec3 V, t;
  double eps, energy_weight;
  bool operator()(double const* const* x, double* r) const {
    SpecularClosures p = base;
    for (size_t i = 0; i < params.size(); ++i) p.*(params[i].field) = float(x[0][i]);
    const SpecularClosureSet c(p, V, t);
    double energy = 0;
    for (size_t k = 0; k < s.L.size(); ++k) {
      const double ck = c.eval(s.L[k]);
      const double e = (ck - s.model[k]) / s.albedo;
      r[k] = std::sqrt(s.dw[k]) * e / std::sqrt(std::sqrt(e * e + eps * eps) + eps);
      energy += ck * s.dw[k];
    }
    // The closures' albedo held to the model's: L1 alone would rather drop energy than spread
    // it where the shapes differ.
    r[s.L.size()] = energy_weight * (energy / s.albedo - 1.0);
    return true;
  }
};

/// Minimise from `start`; returns the fitted closures (only `params` move).
SpecularClosures solve(const Samples& s, const std::vector<Param>& params,
                       const SpecularClosures& start, vec3 V, vec3 t,
                       const ClosureFitOptions& o) {
  std::vector<double> x(params.size());
  for (size_t i = 0; i < params.size(); ++i)
    x[i] = std::clamp(double(start.*(params[i].field)), params[i].lo, params[i].hi);
  auto* cost = new ceres::DynamicNumericDiffCostFunction<HemisphereCost>(
      new HemisphereCost{s, params, start, V, t, o.charbonnier_eps, o.energy_weight});
  cost->AddParameterBlock(int(params.size()));
  cost->SetNumResiduals(int(s.L.size()) + 1);
  ceres::Problem pb;
  pb.AddResidualBlock(cost, nullptr, x.data());
  for (size_t i = 0; i < params.size(); ++i) {
    pb.SetParameterLowerBound(x.data(), int(i), params[i].lo);
    pb.SetParameterUpperBound(x.data(), int(i), params[i].hi);
  }
  ceres::Solver::Options so;
  so.linear_solver_type = ceres::DENSE_QR;
  so.max_num_iterations = o.max_iterations;
  so.num_threads = 1;  // the callers run cells in parallel
  so.logging_type = ceres::SILENT;
  ceres::Solver::Summary sum;
  ceres::Solve(so, &pb, &sum);
  SpecularClosures p = start;
  for (size_t i = 0; i < params.size(); ++i) p.*(params[i].field) = float(x[i]);
  return p;
}

}  // namespace

namespace {

void model_samples(vec3 V, vec3 t, float a, float T, int n, int m, Samples& refl,
                   Samples& trans) {
  cone_quadrature(t, -dot(V, t), a, n, m, [&](vec3 L, double dw) {
    if (L.z > 1e-7f) {
      const double f = surface_specular_reflect(L, V, t, a, T) * L.z;
      refl.L.push_back(L), refl.dw.push_back(dw), refl.model.push_back(f);
      refl.albedo += f * dw;
    } else if (L.z < -1e-7f) {
      const double f = surface_specular_transmit(L, V, t, a, T) * -L.z;
      trans.L.push_back(L), trans.dw.push_back(dw), trans.model.push_back(f);
      trans.albedo += f * dw;
    }
  });
}

}  // namespace

SpecularEnergies specular_closure_energies(const SpecularClosures& p, vec3 V, vec3 t, float a,
                                           int n, int m) {
  // Each closure on a quadrature as wide as its own lobe across the cone (and at least the
  // model's): a broad closure on the model's narrow quadrature is integrated badly.
  SpecularEnergies e;
  SpecularClosures ggx, hair;
  ggx.ggx_w = 1, ggx.ggx_ax = p.ggx_ax, ggx.ggx_ay = p.ggx_ay;
  hair.ht_w = 1, hair.ht_r1 = p.ht_r1, hair.ht_r2 = p.ht_r2;
  const SpecularClosureSet g(ggx, V, t), h(hair, V, t);
  double eg = 0, eh = 0;
  if (p.ggx_w > 0)
    cone_quadrature(t, -dot(V, t), std::max(a, p.ggx_ax), n, m, [&](vec3 L, double dw) {
      if (L.z > 0) eg += g.eval(L) * dw;
    });
  if (p.ht_w > 0)
    cone_quadrature(t, -dot(V, t), std::max(a, p.ht_r1), n, m, [&](vec3 L, double dw) {
      if (L.z < 0) eh += h.eval(L) * dw;
    });
  e.reflect = p.ggx_w * eg;
  e.transmit = p.ht_w * eh + p.tl_w;  // translucent(N) carries exactly its weight
  return e;
}

ClosureFit fit_specular_closures(vec3 V, vec3 t, float a, float T, const ClosureFitOptions& o) {
  Samples refl, trans, jrefl, jtrans;  // the fit's samples, the judge's
  model_samples(V, t, a, T, o.n, o.m, refl, trans);
  model_samples(V, t, a, T, o.judge_n, o.judge_m, jrefl, jtrans);
  ClosureFit out;
  out.A_rs = jrefl.albedo, out.A_ts = jtrans.albedo;

  // The unfitted mapping (closure_mapping.h before issue 31): GGX (a, 1) rescaled to A_rs,
  // translucency with A_ts; the first start of both fits.
  SpecularClosures before;
  before.ggx_ax = a, before.ggx_ay = 1, before.ggx_w = 1;
  before.tl_w = 1;
  before.ht_r1 = std::max(a, 0.01f), before.ht_r2 = 1;
  rescale_to_model(jrefl.albedo, true, before, V, t, a, o);
  rescale_to_model(jtrans.albedo, false, before, V, t, a, o);
  out.refl_before = relative_l1(jrefl, before, V, t);
  out.trans_before = relative_l1(jtrans, before, V, t);

  // Closures narrower than half the model's lobe cannot help it, and could hide between the
  // fit's samples.
  using S = SpecularClosures;
  const double w0 = std::max(0.5 * a, double(LOOM_SGGX_MIN_ROUGHNESS));
  const std::vector<Param> pr = {{&S::ggx_w, 0, 20}, {&S::ggx_ax, w0, 1}, {&S::ggx_ay, w0, 1}};
  const std::vector<Param> pt = {
      {&S::ht_w, 0, 4}, {&S::ht_r1, w0, 1}, {&S::ht_r2, 0.25, 1}, {&S::tl_w, 0, 4}};
  // Transmission starts from the hair closure carrying the model's albedo alone (from the
  // unfitted Lambertian start the hair closure's roughnesses have no gradient).
  SpecularClosures hair = before;
  hair.ht_w = float(trans.albedo), hair.tl_w = 0;

  SpecularClosures best = before;
  out.refl_after = out.refl_before, out.trans_after = out.trans_before;
  auto consider = [&](const Samples& s, const Samples& judge, const std::vector<Param>& params,
                      const SpecularClosures& start, double& after) {
    if (s.albedo <= 1e-8 || judge.albedo <= 1e-8) return;
    SpecularClosures p = solve(s, params, start, V, t, o);
    rescale_to_model(judge.albedo, &judge == &jrefl, p, V, t, a, o);
    const double e = relative_l1(judge, p, V, t);
    if (!(e < after)) return;
    after = e;
    for (const Param& q : params) best.*(q.field) = p.*(q.field);
  };
  consider(refl, jrefl, pr, before, out.refl_after);
  consider(trans, jtrans, pt, hair, out.trans_after);
  out.p = best;
  return out;
}

}  // namespace loom
