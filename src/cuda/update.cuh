// The paper's updater on the device, one object at a time: __host__ __device__, so the kernel
// (kernels.cu) and test_cuda_twin, which holds it to the host's updater bit for bit, run the
// same code. SPDX-License-Identifier: MIT
#pragma once

#include <cfloat>
#include <cmath>
#include <cstdint>

namespace bpx_update {

/// Object i's box from its centre (centres: x, y, z per object) and its stored origin-centred
/// minima (three planes): min = centre + minimum, max = centre - minimum, single precision, as
/// bpx_world_update_centres computes them (one addition each: nothing to contract, and no fast
/// math in this build, so subnormals are kept as the host keeps them). Returns the first axis
/// whose box is not finite (a NaN or infinite centre, or an overflow), else -1.
__host__ __device__ inline int box_of(const float *centres, const float *mx, const float *my,
                                      const float *mz, uint32_t i, float lo[3], float hi[3])
{
    const float *minima[3] = {mx, my, mz};
    int bad = -1;
    for (int a = 2; a >= 0; a--) {
        float c = centres[3 * (size_t)i + a], m = minima[a][i];
        lo[a] = c + m;
        hi[a] = c - m;
        if (!(-FLT_MAX <= lo[a] && hi[a] <= FLT_MAX))
            bad = a;
    }
    return bad;
}

/// The host's rule for a caller's box (src/core/validate.c), as the device checks it: 4 + axis
/// for the first non-finite coordinate (min before max, axis by axis), else 8 + axis for the
/// first min > max, else 0.
__host__ __device__ inline uint32_t box_check(const float min[3], const float max[3])
{
    uint32_t code = 0;
    for (int a = 2; a >= 0; a--)
        if (!(min[a] <= max[a]))
            code = 2u * 4u + (uint32_t)a;
    for (int a = 2; a >= 0; a--)
        if (!isfinite(min[a]) || !isfinite(max[a]))
            code = 1u * 4u + (uint32_t)a;
    return code;
}

} // namespace bpx_update
