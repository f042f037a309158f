// The opencl backend's updater: the world's boxes, its centres (with the minima kept on the
// device) or the caller's device buffer of boxes or of centres, turned into keys on the device.

#include <string.h>

#include "state.h"

// Initialisation phase: the minima cross once (after each load_extents), as three planes of
// cycle->n floats.
bpx_status bpx__cl_upload_minima(bpx_cl_state *st, const bpx_cycle *cycle)
{
    if (st->minima_on_device)
        return BPX_OK;
    size_t plane = (size_t)cycle->n * sizeof(float);
    TRY(bpx__cl_dbuf_reserve(st, &st->minima, 3 * plane));
    TRY(bpx__cl_pinned_reserve(st, &st->up, 3 * plane));
    for (int a = 0; a < 3; a++)
        memcpy((char *)st->up.host + a * plane, cycle->extents.minima[a], plane);
    TRY(bpx__cl_write_buffer(st, st->minima.mem, 0, 3 * plane, st->up.host, true));
    st->minima_on_device = true;
    return BPX_OK;
}

// ---------------------------------------------------------------------------------------------
// Updater: boxes [first, first + count) of the world onto the device as keys, padded.

bpx_status bpx__cl_upload_keys(bpx_cl_state *st, const bpx_cycle *cycle, uint32_t first,
                               uint32_t count, uint32_t padded, size_t region_offset,
                               bpx_cl_buffer *lo, bpx_cl_buffer *hi)
{
    TRY(bpx__cl_dbuf_reserve(st, lo, (size_t)padded * 16));
    TRY(bpx__cl_dbuf_reserve(st, hi, (size_t)padded * 16));
    cl_uint first_arg = first, count_arg = count, padded_arg = padded;
    size_t global = round_up(padded, st->tile);
    bool whole = first == 0 && count == cycle->n;
    if (st->source == SOURCE_BUFFER) {
        // Already on the device: the caller's bpx_box array, read in place.
        cl_uint box_stride = 6, plane = 1;
        const bpx_cl_arg args[] = {ARG(st->user_buffer), ARG(box_stride), ARG(plane),
                                   ARG(first_arg),       ARG(count_arg),  ARG(padded_arg),
                                   ARG(lo->mem),         ARG(hi->mem)};
        return bpx__cl_launch(st, K_CONVERT, global, 0, 8, args);
    }
    if (st->source == SOURCE_CENTRES_BUFFER) {
        // The caller's centres, read in place, any block of them: the minima are whole planes.
        TRY(bpx__cl_upload_minima(st, cycle));
        cl_uint stride = cycle->n;
        const bpx_cl_arg args[] = {ARG(st->user_buffer), ARG(st->minima.mem), ARG(stride),
                                   ARG(first_arg),       ARG(count_arg),      ARG(padded_arg),
                                   ARG(lo->mem),         ARG(hi->mem)};
        return bpx__cl_launch(st, K_UPDATE, global, 0, 8, args);
    }
    if (st->source == SOURCE_CENTRES && whole) {
        size_t plane = (size_t)count * sizeof(float);
        TRY(bpx__cl_upload_minima(st, cycle));
        TRY(bpx__cl_dbuf_reserve(st, &st->input, 3 * plane));
        TRY(bpx__cl_write_buffer(st, st->input.mem, 0, 3 * plane, st->up_centres.host, false));
        cl_uint stride = count;
        const bpx_cl_arg args[] = {ARG(st->input.mem), ARG(st->minima.mem), ARG(stride),
                                   ARG(first_arg),     ARG(count_arg),      ARG(padded_arg),
                                   ARG(lo->mem),       ARG(hi->mem)};
        return bpx__cl_launch(st, K_UPDATE, global, 0, 8, args);
    }
    // The world's boxes as six planes (x min, y min, z min, x max, y max, z max), at
    // region_offset in the pinned staging and in the device's input: while streaming, a row
    // block and a column block are in flight together, in two regions.
    size_t plane = (size_t)count * sizeof(float);
    TRY(bpx__cl_pinned_reserve(st, &st->up, region_offset + 6 * plane));
    TRY(bpx__cl_dbuf_reserve(st, &st->input, region_offset + 6 * plane));
    char *stage = (char *)st->up.host + region_offset;
    for (int a = 0; a < 3; a++) {
        memcpy(stage + a * plane, cycle->boxes.lo[a] + first, plane);
        memcpy(stage + (3 + a) * plane, cycle->boxes.hi[a] + first, plane);
    }
    TRY(bpx__cl_write_buffer(st, st->input.mem, region_offset, 6 * plane, stage, false));
    // Box k's floats start at float (region_offset / 4 + k), planes `count` floats apart.
    cl_uint box_stride = 1, plane_arg = count;
    cl_uint start = (cl_uint)(region_offset / sizeof(float));
    const bpx_cl_arg args[] = {ARG(st->input.mem), ARG(box_stride), ARG(plane_arg), ARG(start),
                               ARG(count_arg),     ARG(padded_arg), ARG(lo->mem),   ARG(hi->mem)};
    return bpx__cl_launch(st, K_CONVERT, global, 0, 8, args);
}
