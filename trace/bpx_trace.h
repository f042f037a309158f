// bpx trace: the AABB-trace file, every cycle's boxes of a simulation, for replay by the
// benchmark, the tests and other tools. SPDX-License-Identifier: MIT
//
// Format, version 1. All integers and floats little-endian; floats IEEE-754 binary32.
//
//   offset  size  field
//   0       8     magic, the ASCII bytes "BPXTRACE"
//   8       4     u32 version = 1
//   12      4     u32 n, boxes per cycle (0 .. BPX_MAX_BOXES)
//   16      8     u64 cycle count
//   24      4     u32 floats per box = 6
//   28      4     u32 reserved = 0
//   32      ...   cycles, one after another; cycle c starts at byte 32 + c * n * 24
//                 each cycle: n boxes; each box 6 floats, the bpx_box order:
//                 min x, min y, min z, max x, max y, max z
//
// The file is exactly 32 + cycle_count * n * 24 bytes. Every box is valid for bpx: finite
// coordinates and min <= max on each axis. The writer guarantees both; the reader checks both
// and rejects a short file, a longer file, a bad header or a bad box with an error that names the
// byte offset. A writer that is interrupted leaves cycle count 0 in the header (it is written at
// close), which the reader reports as trailing data.
//
// The reader trusts no size in the header beyond the file's length: it allocates at most one
// cycle's bytes, and only when the file holds a cycle. Cycles of n = 0 take no bytes, so their
// count is bounded by nothing in the file; bpx_trace_load does not iterate over them.
//
// Library code: never prints, never exits; every error is a status plus a message.
#pragma once

#include <stdint.h>

#include <bpx/types.h>

#ifdef __cplusplus
extern "C" {
#endif

#define BPX_TRACE_MAGIC "BPXTRACE"
#define BPX_TRACE_VERSION 1u
/// Bytes before the first cycle.
#define BPX_TRACE_HEADER_BYTES 32u
/// Bytes of one box in the file (6 x float32).
#define BPX_TRACE_BOX_BYTES 24u

typedef enum bpx_trace_status {
    BPX_TRACE_OK = 0,
    BPX_TRACE_END,             ///< read_cycle: no more cycles (not an error)
    BPX_TRACE_ERR_ARGUMENT,    ///< a null pointer or an out-of-range argument
    BPX_TRACE_ERR_IO,          ///< the operating system refused: open, read, write, seek
    BPX_TRACE_ERR_NO_MEMORY,   ///< an allocation failed
    BPX_TRACE_ERR_BAD_MAGIC,   ///< not a trace file: the first 8 bytes are not "BPXTRACE"
    BPX_TRACE_ERR_BAD_VERSION, ///< a version this reader does not know
    BPX_TRACE_ERR_BAD_HEADER,  ///< short header, floats per box != 6, reserved != 0, n too big
    BPX_TRACE_ERR_TRUNCATED,   ///< the file ends before the cycles its header announces
    BPX_TRACE_ERR_TRAILING,    ///< bytes after the last announced cycle
    BPX_TRACE_ERR_BAD_BOX,     ///< a NaN or infinite coordinate, or min > max
} bpx_trace_status;

/// Detail of the last error: the status, the byte offset in the file where the problem is
/// (UINT64_MAX when none applies) and an English message that names the file and the offset.
typedef struct bpx_trace_error {
    bpx_trace_status status;
    uint64_t offset;
    char message[384];
} bpx_trace_error;

/// What the header says.
typedef struct bpx_trace_header {
    uint32_t version;     ///< BPX_TRACE_VERSION
    uint32_t box_count;   ///< n, boxes per cycle
    uint64_t cycle_count; ///< cycles in the file
} bpx_trace_header;

/// Short static name of a status ("truncated", "bad box", ...).
const char *bpx_trace_status_string(bpx_trace_status status);

// ---------------------------------------------------------------------------------------------
// Reading

typedef struct bpx_trace_reader bpx_trace_reader;

/// Opens a trace and checks its header against the file's size (so a truncated or overlong file
/// is rejected here, before any cycle is read). err may be NULL. On error *out is NULL.
bpx_trace_status bpx_trace_open(const char *path, bpx_trace_reader **out, bpx_trace_error *err);

/// The header of an open trace. Valid until bpx_trace_close.
const bpx_trace_header *bpx_trace_header_of(const bpx_trace_reader *reader);

/// Reads the next cycle: n boxes into out (room for header.box_count boxes). Returns OK, END after
/// the last cycle (out untouched), or an error (BAD_BOX names cycle, box, axis and byte offset;
/// IO, TRUNCATED if the file shrank since open). err may be NULL.
bpx_trace_status bpx_trace_read_cycle(bpx_trace_reader *reader, bpx_box *out, bpx_trace_error *err);

/// Positions the reader so the next read_cycle returns cycle `cycle` (0-based; cycle_count is
/// allowed and makes the next read return END). err may be NULL.
bpx_trace_status bpx_trace_seek_cycle(bpx_trace_reader *reader, uint64_t cycle,
                                      bpx_trace_error *err);

/// Closes the file and frees the reader. NULL is allowed.
void bpx_trace_close(bpx_trace_reader *reader);

/// Reads a whole trace into memory: *boxes receives cycle_count * n boxes, cycle after cycle,
/// to be released with free() (NULL when there are none). header may be NULL, err may be NULL.
/// On error nothing is allocated.
bpx_trace_status bpx_trace_load(const char *path, bpx_trace_header *header, bpx_box **boxes,
                                bpx_trace_error *err);

// ---------------------------------------------------------------------------------------------
// Writing

typedef struct bpx_trace_writer bpx_trace_writer;

/// Creates (or truncates) path and writes a header for n boxes per cycle and 0 cycles; the count
/// is written by bpx_trace_writer_close. err may be NULL. On error *out is NULL.
bpx_trace_status bpx_trace_writer_open(const char *path, uint32_t box_count, bpx_trace_writer **out,
                                       bpx_trace_error *err);

/// Appends one cycle: n boxes. Each must be valid (finite, min <= max); an invalid box fails with
/// BAD_BOX and writes nothing of this cycle. err may be NULL.
bpx_trace_status bpx_trace_write_cycle(bpx_trace_writer *writer, const bpx_box *boxes,
                                       bpx_trace_error *err);

/// Cycles written so far.
uint64_t bpx_trace_writer_cycles(const bpx_trace_writer *writer);

/// Writes the cycle count into the header, flushes and closes the file, and frees the writer
/// (always, even on error). NULL is allowed (returns OK). err may be NULL.
bpx_trace_status bpx_trace_writer_close(bpx_trace_writer *writer, bpx_trace_error *err);

#ifdef __cplusplus
}
#endif
