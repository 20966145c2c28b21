#include "loom/spectral_upsampling.h"

#include <ceres/ceres.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>

namespace loom {

namespace {

template <class T>
T sigmoid(const T& x) {
  using std::sqrt;
  return T(0.5) + x / (T(2.0) * sqrt(T(1.0) + x * x));
}

double t_of(double lambda_nm) { return (lambda_nm - kLambdaMinNm) / (kLambdaMaxNm - kLambdaMinNm); }

/// CIELAB's f(t) (CIE 15), templated for Ceres' automatic derivatives.
template <class T>
T lab_f(const T& t) {
  constexpr double d = 6.0 / 29.0;
  if (t > T(d * d * d)) return ceres::cbrt(t);
  return t / T(3 * d * d) + T(4.0 / 29.0);
}

template <class T>
void xyz_to_lab(const T xyz[3], const std::array<double, 3>& white, T lab[3]) {
  const T fx = lab_f(xyz[0] / T(white[0])), fy = lab_f(xyz[1] / T(white[1])),
          fz = lab_f(xyz[2] / T(white[2]));
  lab[0] = T(116) * fy - T(16);
  lab[1] = T(500) * (fx - fy);
  lab[2] = T(200) * (fy - fz);
}

struct LabResidual {
  const SpectralRgb* w;
  const std::array<std::array<double, 3>, 3>* to_xyz;
  std::array<double, 3> white, target_lab;
  template <class T>
  bool operator()(const T* c, T* r) const {
    T rgb[3] = {T(0), T(0), T(0)};
    for (size_t k = 0; k < w->lambda_nm.size(); ++k) {
      const double t = t_of(w->lambda_nm[k]);
      const T s = sigmoid(c[0] * t * t + c[1] * t + c[2]);
      for (int ch = 0; ch < 3; ++ch) rgb[ch] += T(w->weight[k][size_t(ch)]) * s;
    }
    T xyz[3];
    for (int i = 0; i < 3; ++i)
      xyz[i] = T((*to_xyz)[size_t(i)][0]) * rgb[0] + T((*to_xyz)[size_t(i)][1]) * rgb[1] +
               T((*to_xyz)[size_t(i)][2]) * rgb[2];
    T lab[3];
    xyz_to_lab(xyz, white, lab);
    for (int i = 0; i < 3; ++i) r[i] = lab[i] - T(target_lab[size_t(i)]);
    return true;
  }
};

}  // namespace

double SigmoidSpectrum::operator()(double lambda_nm) const {
  const double t = t_of(lambda_nm);
  return sigmoid(coeffs[0] * t * t + coeffs[1] * t + coeffs[2]);
}

SpectralUpsampler::SpectralUpsampler(const ColourConverter& cc, double step_nm)
    : w_(spectral_rgb(cc, step_nm)) {
  const auto M = cc.xyz_to_linear_matrix();
  Eigen::Matrix3d m;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) m(i, j) = M[size_t(i)][size_t(j)];
  const Eigen::Matrix3d inv = m.inverse();
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) rgb_to_xyz_[size_t(i)][size_t(j)] = inv(i, j);
  for (int i = 0; i < 3; ++i) white_xyz_[size_t(i)] = inv(i, 0) + inv(i, 1) + inv(i, 2);
}

std::array<double, 3> SpectralUpsampler::rgb(const SigmoidSpectrum& s) const {
  std::array<double, 3> out{0, 0, 0};
  for (size_t k = 0; k < w_.lambda_nm.size(); ++k) {
    const double v = s(w_.lambda_nm[k]);
    for (int c = 0; c < 3; ++c) out[size_t(c)] += w_.weight[k][size_t(c)] * v;
  }
  return out;
}

std::array<double, 3> SpectralUpsampler::lab(const std::array<double, 3>& rgb) const {
  double xyz[3], out[3];
  for (int i = 0; i < 3; ++i)
    xyz[i] = rgb_to_xyz_[size_t(i)][0] * rgb[0] + rgb_to_xyz_[size_t(i)][1] * rgb[1] +
             rgb_to_xyz_[size_t(i)][2] * rgb[2];
  xyz_to_lab(xyz, white_xyz_, out);
  return {out[0], out[1], out[2]};
}

SigmoidSpectrum SpectralUpsampler::fit(const std::array<double, 3>& rgb_in) const {
  std::array<double, 3> target{};
  for (int c = 0; c < 3; ++c) {
    const double v = std::isfinite(rgb_in[size_t(c)]) ? rgb_in[size_t(c)] : 0.0;
    target[size_t(c)] = std::clamp(v, 1e-4, 1 - 1e-4);
  }
  // Continuation (Jakob and Hanika, section 4.2): from the grey of the target's mean, whose
  // spectrum is the constant S(c2), towards the target in a few steps.
  const double g = (target[0] + target[1] + target[2]) / 3;
  double c[3] = {0, 0, (2 * g - 1) / std::sqrt(1 - (2 * g - 1) * (2 * g - 1))};  // S^-1(g)
  constexpr int kSteps = 8;
  for (int step = 1; step <= kSteps; ++step) {
    const double a = double(step) / kSteps;
    std::array<double, 3> tgt{};
    for (int i = 0; i < 3; ++i) tgt[size_t(i)] = (1 - a) * g + a * target[size_t(i)];
    auto* cost = new ceres::AutoDiffCostFunction<LabResidual, 3, 3>(
        new LabResidual{&w_, &rgb_to_xyz_, white_xyz_, lab(tgt)});
    ceres::Problem pb;
    pb.AddResidualBlock(cost, nullptr, c);
    ceres::Solver::Options o;
    o.linear_solver_type = ceres::DENSE_QR;
    o.max_num_iterations = step == kSteps ? 100 : 30;
    o.function_tolerance = 1e-14;
    o.parameter_tolerance = 1e-14;
    o.logging_type = ceres::SILENT;
    o.num_threads = 1;
    ceres::Solver::Summary sum;
    ceres::Solve(o, &pb, &sum);
  }
  return SigmoidSpectrum{{c[0], c[1], c[2]}};
}

}  // namespace loom
