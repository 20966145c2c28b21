#include "loom/delta_e.h"

#include <cmath>

namespace loom {

double delta_e_2000(const Lab& x, const Lab& y) {
  const double deg = M_PI / 180;
  const double c1 = std::hypot(x[1], x[2]), c2 = std::hypot(y[1], y[2]);
  const double cm = 0.5 * (c1 + c2), cm7 = std::pow(cm, 7);
  const double g = 0.5 * (1 - std::sqrt(cm7 / (cm7 + std::pow(25.0, 7))));
  const double a1 = (1 + g) * x[1], a2 = (1 + g) * y[1];
  const double cp1 = std::hypot(a1, x[2]), cp2 = std::hypot(a2, y[2]);
  auto hue = [&](double b, double a) {
    if (a == 0 && b == 0) return 0.0;
    const double h = std::atan2(b, a) / deg;
    return h < 0 ? h + 360 : h;
  };
  const double h1 = hue(x[2], a1), h2 = hue(y[2], a2);
  const double dl = y[0] - x[0], dc = cp2 - cp1;
  double dh = 0;
  if (cp1 * cp2 != 0) {
    dh = h2 - h1;
    if (dh > 180) dh -= 360;
    if (dh < -180) dh += 360;
  }
  const double dH = 2 * std::sqrt(cp1 * cp2) * std::sin(dh * deg / 2);
  const double lm = 0.5 * (x[0] + y[0]), cpm = 0.5 * (cp1 + cp2);
  double hm = h1 + h2;
  if (cp1 * cp2 != 0) {
    if (std::fabs(h1 - h2) <= 180) hm = 0.5 * (h1 + h2);
    else hm = h1 + h2 < 360 ? 0.5 * (h1 + h2 + 360) : 0.5 * (h1 + h2 - 360);
  }
  const double t = 1 - 0.17 * std::cos((hm - 30) * deg) + 0.24 * std::cos(2 * hm * deg) +
                   0.32 * std::cos((3 * hm + 6) * deg) - 0.20 * std::cos((4 * hm - 63) * deg);
  const double dtheta = 30 * std::exp(-std::pow((hm - 275) / 25, 2));
  const double cpm7 = std::pow(cpm, 7);
  const double rc = 2 * std::sqrt(cpm7 / (cpm7 + std::pow(25.0, 7)));
  const double l50 = (lm - 50) * (lm - 50);
  const double sl = 1 + 0.015 * l50 / std::sqrt(20 + l50);
  const double sc = 1 + 0.045 * cpm, sh = 1 + 0.015 * cpm * t;
  const double rt = -std::sin(2 * dtheta * deg) * rc;
  const double tl = dl / sl, tc = dc / sc, th = dH / sh;
  return std::sqrt(tl * tl + tc * tc + th * th + rt * tc * th);
}

}  // namespace loom
