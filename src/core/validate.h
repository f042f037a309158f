// Input checks shared by every entry point: the error names the first offending box and axis.
#pragma once

#include "bpx/types.h"

/// Fills err (if not NULL) and returns status. index UINT32_MAX / axis -1 when not applicable.
bpx_status bpx__error(bpx_error *err, bpx_status status, uint32_t index, int axis,
                      const char *format, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 5, 6)))
#endif
    ;

/// Clears err to BPX_OK.
void bpx__error_clear(bpx_error *err);

/// First non-finite coordinate, else first min > max.
bpx_status bpx__check_boxes(const bpx_box *boxes, uint32_t n, bpx_error *err);

/// Origin-centred minima (3 per object): finite and <= 0 (maxima are their negation).
bpx_status bpx__check_minima(const float *minima, uint32_t n, bpx_error *err);

/// Centres (3 per object), and the boxes they make with the minima: all finite.
bpx_status bpx__check_centres(const float *centres, const float *const minima[3], uint32_t n,
                              bpx_error *err);
