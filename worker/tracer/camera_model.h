// CameraModel: turns a point on the image plane into a primary ray (pinhole perspective,
// field of view along the smaller image axis, image row 0 at the top).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <numbers>

#include "scene.h"

namespace aliquot {

class CameraModel {
public:
    CameraModel(const Camera& camera, uint32_t width, uint32_t height)
        : origin_(camera.position), width_(float(width)), height_(float(height)) {
        const Vec3 forward = normalize(camera.target - camera.position);
        const Vec3 right = normalize(cross(forward, camera.up));
        const Vec3 up = cross(right, forward);
        const float tan_half =
            std::tan(camera.fov_degrees * float(std::numbers::pi) / 360.0f);
        const float smaller = float(std::min(width, height));
        forward_ = forward;
        right_ = right * (tan_half * float(width) / smaller);
        up_ = up * (tan_half * float(height) / smaller);
    }

    // (px, py) in pixels: x to the right, y downwards, both in [0, width] x [0, height].
    Vec3 direction(float px, float py) const {
        const float sx = 2.0f * px / width_ - 1.0f;
        const float sy = 1.0f - 2.0f * py / height_;
        return normalize(forward_ + right_ * sx + up_ * sy);
    }
    const Vec3& origin() const { return origin_; }

private:
    Vec3 origin_, forward_, right_, up_;
    float width_, height_;
};

}  // namespace aliquot
