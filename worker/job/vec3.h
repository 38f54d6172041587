// Vec3: the one small vector type of the renderer (positions, directions, RGB).
#pragma once

#include <algorithm>
#include <cmath>

namespace aliquot {

struct Vec3 {
    float x = 0, y = 0, z = 0;

    constexpr Vec3() = default;
    constexpr Vec3(float x_, float y_, float z_) : x(x_), y(y_), z(z_) {}
    constexpr explicit Vec3(float v) : x(v), y(v), z(v) {}

    constexpr float operator[](int i) const { return i == 0 ? x : (i == 1 ? y : z); }
    constexpr Vec3 operator+(const Vec3& o) const { return {x + o.x, y + o.y, z + o.z}; }
    constexpr Vec3 operator-(const Vec3& o) const { return {x - o.x, y - o.y, z - o.z}; }
    constexpr Vec3 operator-() const { return {-x, -y, -z}; }
    constexpr Vec3 operator*(const Vec3& o) const { return {x * o.x, y * o.y, z * o.z}; }
    constexpr Vec3 operator*(float s) const { return {x * s, y * s, z * s}; }
    // One division and three products: three divisions cost several times more, and the
    // tracer normalises on every bounce.
    constexpr Vec3 operator/(float s) const {
        const float inv = 1.0f / s;
        return {x * inv, y * inv, z * inv};
    }
    constexpr Vec3& operator+=(const Vec3& o) {
        x += o.x;
        y += o.y;
        z += o.z;
        return *this;
    }
    constexpr Vec3& operator*=(const Vec3& o) {
        x *= o.x;
        y *= o.y;
        z *= o.z;
        return *this;
    }
    constexpr Vec3& operator*=(float s) {
        x *= s;
        y *= s;
        z *= s;
        return *this;
    }
    constexpr bool operator==(const Vec3&) const = default;
};

constexpr Vec3 operator*(float s, const Vec3& v) { return v * s; }
constexpr float dot(const Vec3& a, const Vec3& b) {
    return a.x * b.x + a.y * b.y + a.z * b.z;
}
constexpr Vec3 cross(const Vec3& a, const Vec3& b) {
    return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
inline float length(const Vec3& v) { return std::sqrt(dot(v, v)); }
inline Vec3 normalize(const Vec3& v) { return v / length(v); }
constexpr float max_component(const Vec3& v) { return std::max(v.x, std::max(v.y, v.z)); }
// Rec. 709 luminance, the weights Mitsuba uses for linear sRGB. The coordinator's
// variance and adaptive measures use the double version: they must weigh colour as the
// worker's sum of squared luminance did.
inline constexpr double kLuminanceWeights[3] = {0.212671, 0.715160, 0.072169};
constexpr double luminance(double r, double g, double b) {
    return kLuminanceWeights[0] * r + kLuminanceWeights[1] * g + kLuminanceWeights[2] * b;
}
constexpr float luminance(const Vec3& c) {
    return float(kLuminanceWeights[0]) * c.x + float(kLuminanceWeights[1]) * c.y +
           float(kLuminanceWeights[2]) * c.z;
}
static_assert(float(kLuminanceWeights[0]) == 0.212671f &&
              float(kLuminanceWeights[1]) == 0.715160f &&
              float(kLuminanceWeights[2]) == 0.072169f);
inline bool is_finite(const Vec3& v) {
    return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z);
}

}  // namespace aliquot
