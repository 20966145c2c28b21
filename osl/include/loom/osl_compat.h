// Loom: the one small compatibility layer that lets C++ compile the shared shading math.
//
// Every header in osl/include/loom/ is written in the common subset of OSL and C++:
//   * types `float`, `int`, `vector`, `normal`, `color`, `point` (here one value type `vec3`);
//   * functions declared with LOOM_FN (nothing in OSL, `inline` in C++);
//   * output parameters declared with LOOM_OUT(type) (`output type` in OSL, `type&` in C++);
//   * no `f` literal suffixes, no templates, no pointers, no std::.
// In OSL this file only defines the two macros; in C++ it also defines the vector type and the
// OSL standard-library functions the shared headers use, with OSL's semantics (component-wise
// colour products, `mix`, `clamp`, `step`, `select`-free code, float-only overloads so that
// double literals convert as they would in OSL).
#ifndef LOOM_OSL_COMPAT_H
#define LOOM_OSL_COMPAT_H

#ifndef LOOM_CPP
/* ---------------------------------------------------------------- OSL side */
#define LOOM_FN
#define LOOM_OUT(T) output T
#define LOOM_M_PI M_PI
#else
/* ---------------------------------------------------------------- C++ side */
#include <cmath>
#include <type_traits>

#define LOOM_FN inline
#define LOOM_OUT(T) T&
#define LOOM_M_PI 3.14159265358979323846f

namespace loom::shading {

struct vec3 {
  float x = 0, y = 0, z = 0;
  constexpr vec3() = default;
  constexpr explicit vec3(float s) : x(s), y(s), z(s) {}
  constexpr vec3(float a, float b, float c) : x(a), y(b), z(c) {}
  float& operator[](int i) { return i == 0 ? x : (i == 1 ? y : z); }
  float operator[](int i) const { return i == 0 ? x : (i == 1 ? y : z); }
};
using vector = vec3;
using normal = vec3;
using color = vec3;
using point = vec3;

inline vec3 operator+(vec3 a, vec3 b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
inline vec3 operator-(vec3 a, vec3 b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
inline vec3 operator-(vec3 a) { return {-a.x, -a.y, -a.z}; }
inline vec3 operator*(vec3 a, vec3 b) { return {a.x * b.x, a.y * b.y, a.z * b.z}; }
inline vec3 operator*(vec3 a, float s) { return {a.x * s, a.y * s, a.z * s}; }
inline vec3 operator*(float s, vec3 a) { return a * s; }
inline vec3 operator/(vec3 a, float s) { return {a.x / s, a.y / s, a.z / s}; }
inline vec3 operator/(vec3 a, vec3 b) { return {a.x / b.x, a.y / b.y, a.z / b.z}; }
inline vec3& operator+=(vec3& a, vec3 b) { return a = a + b; }
inline vec3& operator-=(vec3& a, vec3 b) { return a = a - b; }
inline vec3& operator*=(vec3& a, float s) { return a = a * s; }
inline vec3& operator*=(vec3& a, vec3 b) { return a = a * b; }

inline float dot(vec3 a, vec3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
inline vec3 cross(vec3 a, vec3 b) {
  return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
inline float length(vec3 a) { return std::sqrt(dot(a, a)); }
// OSL's normalize returns the zero vector for a zero-length input.
inline vec3 normalize(vec3 a) {
  float l = length(a);
  return l > 0 ? a / l : vec3(0);
}

inline float sqrt(float x) { return std::sqrt(x); }
inline float exp(float x) { return std::exp(x); }
inline float log(float x) { return std::log(x); }
inline float pow(float x, float y) { return std::pow(x, y); }
inline float sin(float x) { return std::sin(x); }
inline float cos(float x) { return std::cos(x); }
inline float tan(float x) { return std::tan(x); }
inline float atan2(float y, float x) { return std::atan2(y, x); }
inline float acos(float x) { return std::acos(x); }
inline float asin(float x) { return std::asin(x); }
inline float floor(float x) { return std::floor(x); }
inline float fabs(float x) { return std::fabs(x); }
inline float abs(float x) { return std::fabs(x); }
inline int abs(int x) { return x < 0 ? -x : x; }
// OSL literals like 0.0 are floats; in C++ they are doubles. min/max therefore take any two
// arithmetic arguments and compute in float, unless both are integers (as in OSL).
template <class A, class B>
inline auto max(A a, B b) {
  if constexpr (std::is_integral_v<A> && std::is_integral_v<B>)
    return int(a) > int(b) ? int(a) : int(b);
  else
    return float(a) > float(b) ? float(a) : float(b);
}
template <class A, class B>
inline auto min(A a, B b) {
  if constexpr (std::is_integral_v<A> && std::is_integral_v<B>)
    return int(a) < int(b) ? int(a) : int(b);
  else
    return float(a) < float(b) ? float(a) : float(b);
}
inline float clamp(float x, float lo, float hi) { return x < lo ? lo : (x > hi ? hi : x); }
inline float mix(float a, float b, float t) { return a * (1 - t) + b * t; }
inline vec3 mix(vec3 a, vec3 b, float t) { return a * (1 - t) + b * t; }
inline float sign(float x) { return x > 0 ? 1.0f : (x < 0 ? -1.0f : 0.0f); }
// OSL's mod: result has the sign of b (like GLSL), unlike C's fmod.
inline float mod(float a, float b) { return a - b * std::floor(a / b); }
inline int isfinite(float x) { return std::isfinite(x) ? 1 : 0; }
inline int isnan(float x) { return std::isnan(x) ? 1 : 0; }

}  // namespace loom::shading
#endif

#endif  // LOOM_OSL_COMPAT_H
