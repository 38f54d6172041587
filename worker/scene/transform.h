// Transform: an affine 4x4 matrix, composed from translate / rotate / scale as scenes
// say.
#pragma once

#include <array>
#include <cmath>
#include <numbers>

#include "vec3.h"

namespace aliquot {

class Transform {
public:
    Transform() : m_{{{1, 0, 0, 0}, {0, 1, 0, 0}, {0, 0, 1, 0}, {0, 0, 0, 1}}} {}

    static Transform translate(const Vec3& t) {
        Transform r;
        r.m_[0][3] = t.x;
        r.m_[1][3] = t.y;
        r.m_[2][3] = t.z;
        return r;
    }
    static Transform scale(const Vec3& s) {
        Transform r;
        r.m_[0][0] = s.x;
        r.m_[1][1] = s.y;
        r.m_[2][2] = s.z;
        return r;
    }
    // Rotation by `degrees` about `axis` (right-handed, as Mitsuba's
    // Transform4f::rotate).
    static Transform rotate(const Vec3& axis, double degrees) {
        const Vec3 a = normalize(axis);
        const double rad = degrees * std::numbers::pi / 180.0;
        const double s = std::sin(rad), c = std::cos(rad), t = 1.0 - c;
        Transform r;
        const double x = a.x, y = a.y, z = a.z;
        r.m_[0] = {t * x * x + c, t * x * y - s * z, t * x * z + s * y, 0};
        r.m_[1] = {t * x * y + s * z, t * y * y + c, t * y * z - s * x, 0};
        r.m_[2] = {t * x * z - s * y, t * y * z + s * x, t * z * z + c, 0};
        return r;
    }

    Transform operator*(const Transform& o) const {
        Transform r;
        for (int i = 0; i < 4; ++i)
            for (int j = 0; j < 4; ++j) {
                double v = 0;
                for (int k = 0; k < 4; ++k) v += m_[i][k] * o.m_[k][j];
                r.m_[i][j] = v;
            }
        return r;
    }

    Vec3 point(const Vec3& p) const {
        return {float(m_[0][0] * p.x + m_[0][1] * p.y + m_[0][2] * p.z + m_[0][3]),
                float(m_[1][0] * p.x + m_[1][1] * p.y + m_[1][2] * p.z + m_[1][3]),
                float(m_[2][0] * p.x + m_[2][1] * p.y + m_[2][2] * p.z + m_[2][3])};
    }
    Vec3 vector(const Vec3& v) const {
        return {float(m_[0][0] * v.x + m_[0][1] * v.y + m_[0][2] * v.z),
                float(m_[1][0] * v.x + m_[1][1] * v.y + m_[1][2] * v.z),
                float(m_[2][0] * v.x + m_[2][1] * v.y + m_[2][2] * v.z)};
    }
    double at(int row, int col) const { return m_[row][col]; }

private:
    // Double precision so that chains of transforms do not drift before the final
    // conversion of each vertex to float.
    std::array<std::array<double, 4>, 4> m_;
};

}  // namespace aliquot
