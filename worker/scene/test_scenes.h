// Small scenes built in code for the tracer's tests, independent of the scene loader.
#pragma once

#include "scene.h"

namespace aliquot::test {

// A rectangle of half-sides (hx, hz) in the plane y = height, centred on the y axis,
// facing +y when `up` and -y otherwise.
inline TriangleMesh horizontal_rectangle(float hx, float hz, float height, bool up) {
    TriangleMesh m;
    m.positions = {
        {-hx, height, -hz}, {hx, height, -hz}, {hx, height, hz}, {-hx, height, hz}};
    // cross(v1 - v0, v2 - v0) points -y for (0,1,2) in this order seen from above.
    if (up)
        m.triangles = {{0, 2, 1}, {0, 3, 2}};
    else
        m.triangles = {{0, 1, 2}, {0, 2, 3}};
    return m;
}

}  // namespace aliquot::test
