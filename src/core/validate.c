#include "validate.h"

#include <float.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <string.h>

static const char axis_names[3] = {'x', 'y', 'z'};

bpx_status bpx__error(bpx_error *err, bpx_status status, uint32_t index, int axis,
                      const char *format, ...)
{
    if (!err)
        return status;
    err->status = status;
    err->index = index;
    err->axis = axis;
    va_list args;
    va_start(args, format);
    vsnprintf(err->message, sizeof err->message, format, args);
    va_end(args);
    return status;
}

void bpx__error_clear(bpx_error *err)
{
    if (!err)
        return;
    err->status = BPX_OK;
    err->index = UINT32_MAX;
    err->axis = -1;
    err->message[0] = '\0';
}

// Names the first problem of a box known to have one.
static bpx_status describe_bad_box(const bpx_box *b, uint32_t i, bpx_error *err)
{
    for (int a = 0; a < 3; a++) {
        if (!isfinite(b->min[a]))
            return bpx__error(err, BPX_ERR_NOT_FINITE, i, a, "box %u: min %c is %g", i,
                              axis_names[a], (double)b->min[a]);
        if (!isfinite(b->max[a]))
            return bpx__error(err, BPX_ERR_NOT_FINITE, i, a, "box %u: max %c is %g", i,
                              axis_names[a], (double)b->max[a]);
    }
    for (int a = 0; a < 3; a++)
        if (!(b->min[a] <= b->max[a]))
            return bpx__error(err, BPX_ERR_MIN_GREATER_THAN_MAX, i, a,
                              "box %u: min %c (%.9g) > max %c (%.9g)", i, axis_names[a],
                              (double)b->min[a], axis_names[a], (double)b->max[a]);
    return BPX_OK;
}

// Valid iff -FLT_MAX <= min <= max <= FLT_MAX on each axis: any NaN fails a comparison, and an
// infinity fails a bound (min = +inf would need max = +inf, which fails the upper bound).
static inline int box_is_valid(const bpx_box *b)
{
    int ok = 1;
    for (int a = 0; a < 3; a++)
        ok &= (-FLT_MAX <= b->min[a]) & (b->min[a] <= b->max[a]) & (b->max[a] <= FLT_MAX);
    return ok;
}

bpx_status bpx__check_boxes(const bpx_box *boxes, uint32_t n, bpx_error *err)
{
    for (uint32_t i = 0; i < n; i++)
        if (!box_is_valid(&boxes[i]))
            return describe_bad_box(&boxes[i], i, err);
    return BPX_OK;
}

bpx_status bpx__check_minima(const float *minima, uint32_t n, bpx_error *err)
{
    for (uint32_t i = 0; i < n; i++) {
        for (int a = 0; a < 3; a++) {
            float m = minima[3 * (size_t)i + a];
            if (!isfinite(m))
                return bpx__error(err, BPX_ERR_NOT_FINITE, i, a, "object %u: minimum %c is %g",
                                  i, axis_names[a], (double)m);
            if (!(m <= 0.0f))
                return bpx__error(err, BPX_ERR_MIN_GREATER_THAN_MAX, i, a,
                                  "object %u: origin-centred minimum %c (%.9g) > 0, so min > max",
                                  i, axis_names[a], (double)m);
        }
    }
    return BPX_OK;
}

bpx_status bpx__check_centres(const float *centres, const float *const minima[3], uint32_t n,
                              bpx_error *err)
{
    for (uint32_t i = 0; i < n; i++) {
        for (int a = 0; a < 3; a++) {
            float c = centres[3 * (size_t)i + a];
            float m = minima[a][i];
            if (!isfinite(c))
                return bpx__error(err, BPX_ERR_NOT_FINITE, i, a, "object %u: centre %c is %g", i,
                                  axis_names[a], (double)c);
            // c + m <= c <= c - m always holds (rounding is monotone), so only overflow can fail.
            if (!isfinite(c + m) || !isfinite(c - m))
                return bpx__error(err, BPX_ERR_NOT_FINITE, i, a,
                                  "object %u: box %c overflows (centre %.9g, half extent %.9g)", i,
                                  axis_names[a], (double)c, (double)-m);
        }
    }
    return BPX_OK;
}
