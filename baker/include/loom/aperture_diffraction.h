// Gaussian-beam aperture diffraction (ray-wave supplement, section 4, Eq. S.23-S.36).
//
// A Gaussian-windowed plane wave (Eq. S.25, waist w_0) passes a rectangular aperture
// A = [x_w, x_e] x [y_s, y_n] (lengths in um, in the aperture plane, beam centre at the origin).
// Its far field is, up to a phase and 1/R, the windowed Fourier transform K of Eq. S.34,
//   K(A; f_x, f_y) = int_{x_w}^{x_e} int_{y_s}^{y_n} exp(-(x^2 + y^2) / w_0^2)
//                    exp(-2 pi i (f_x x + f_y y)) dy dx,
// and the intensity is Eq. S.35, I = (|xi_i.z| + |xi_o.z|)^2 / (4 lambda^2) |K|^2 with
// f = (xi_i.xy + xi_o.xy) / lambda (osl/include/loom/diffraction_table.h has the shader's side).
//
// Closed form. K separates into two 1D factors J(a, b; f) = int_a^b exp(-x^2/w^2 - 2 pi i f x) dx.
// Completing the square with z(x) = x / w + i pi f w,
//   J = w sqrt(pi) / 2 exp(-(pi f w)^2) [erf(z(b)) - erf(z(a))].
// Written naively this overflows and cancels: erf of a complex argument with a large imaginary
// part is astronomically large while exp(-(pi f w)^2) underflows, and erf(z(b)) - erf(z(a)) loses
// everything when both are close to +-1. We use instead, with z = beta + i gamma,
//   E(z) := exp(-gamma^2) erfc(z)
//         = exp(-beta^2) exp(-2 i beta gamma) w(i z)                       if beta >= 0,
//         = 2 exp(-gamma^2) - exp(-beta^2) exp(-2 i beta gamma) w(-i z)    if beta < 0,
// where w is Faddeeva's function (libcerf), evaluated only in the upper half plane where
// |w| <= 1; then J = w sqrt(pi) / 2 [E(z(a)) - E(z(b))]. Every term is bounded; E(-inf) = 2
// exp(-gamma^2) and E(+inf) = 0 give unbounded apertures. The one remaining cancellation, a
// narrow interval (both ends giving nearly equal E), is avoided by integrating such intervals
// directly with 16-point Gauss-Legendre quadrature, exact to double precision there (interval
// at most w/2 wide and at most 1.3 periods of the phase).
#pragma once

#include <array>
#include <complex>

namespace loom {

/// A rectangular aperture in the aperture plane, um, relative to the beam centre. Bounds may be
/// infinite (an unbounded side). x_w <= x_e and y_s <= y_n.
struct Aperture {
  double xw = -5, xe = 5, ys = -5, yn = 5;
};

/// J(a, b; f) = int_a^b exp(-x^2 / w0^2) exp(-2 pi i f x) dx; a, b in um (may be infinite),
/// f in 1/um, w0 > 0 in um.
std::complex<double> gaussian_window_integral(double a, double b, double f, double w0);

/// Eq. S.34: K(A; f_x, f_y), um^2.
std::complex<double> aperture_K(const Aperture& A, double fx, double fy, double w0);

/// Eq. S.35: the diffracted intensity for directions xi_i (towards the light) and xi_o (towards
/// the receiver, on the far side), both unit vectors in the aperture's frame; lambda in um.
/// Units um^2 (|K|^2 / lambda^2); divide by beam_power(w0) for a fraction of the beam.
double aperture_intensity(const Aperture& A, double w0, double lambda_um,
                          const std::array<double, 3>& xi_i, const std::array<double, 3>& xi_o);

/// The power of the Gaussian beam of Eq. S.25 across its whole plane: pi w0^2 / 2.
double beam_power(double w0);
/// The power the aperture lets through: int_A exp(-2 (x^2 + y^2) / w0^2) (closed form, real erf).
/// By Parseval this is the integral of |K|^2 over all frequencies.
double aperture_power(const Aperture& A, double w0);

/// Section 4.3: the aperture past a ply's edge for a beam centred at distance h (um) from the
/// ply's centre line, ply radius R: [R - |h|, d_cut] x [-d_cut, d_cut], x pointing away from the
/// ply's centre. d_cut = LOOM_DIFFRACTION_DCUT_WAISTS w0 (diffraction_table.h).
Aperture ply_edge_aperture(double R, double h, double d_cut);

}  // namespace loom
