#include "sort.h"

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

void bpx__radix_sort(uint32_t *keys, uint32_t *ids, uint32_t *scratch_keys,
                     uint32_t *scratch_ids, uint32_t n)
{
    enum { BITS = 11, BUCKETS = 1 << BITS };
    uint32_t *src_k = keys, *src_i = ids, *dst_k = scratch_keys, *dst_i = scratch_ids;
    for (int shift = 0; shift < 32; shift += BITS) {
        uint32_t counts[BUCKETS + 1] = {0};
        for (uint32_t k = 0; k < n; k++)
            counts[((src_k[k] >> shift) & (BUCKETS - 1)) + 1]++;
        for (int b = 0; b < BUCKETS; b++)
            counts[b + 1] += counts[b];
        for (uint32_t k = 0; k < n; k++) {
            uint32_t slot = counts[(src_k[k] >> shift) & (BUCKETS - 1)]++;
            dst_k[slot] = src_k[k];
            dst_i[slot] = src_i[k];
        }
        uint32_t *t = src_k;
        src_k = dst_k;
        dst_k = t;
        t = src_i;
        src_i = dst_i;
        dst_i = t;
    }
    // Three passes (0, 11, 22) leave the result in the scratch arrays: copy it home.
    if (src_k != keys) {
        memcpy(keys, src_k, sizeof(uint32_t) * n);
        memcpy(ids, src_i, sizeof(uint32_t) * n);
    }
}

// One gathered line out to memory, bypassing the cache: no read for ownership of a line that
// is about to be overwritten.
static inline void put_line(uint64_t *to, const uint64_t *line)
{
#if defined(__SSE2__)
    const __m128i *from = (const __m128i *)(const void *)line;
    __m128i *d = (__m128i *)(void *)to;
    for (int k = 0; k < 4; k++)
        _mm_stream_si128(d + k, _mm_load_si128(from + k));
#else
    memcpy(to, line, BPX_RADIX_LINE * sizeof *to);
#endif
}

// One pass by the digit at `shift`: counts[b] is where bucket b starts in dst. Past
// BPX_RADIX_STREAM_WORDS the words leave the caches between passes (L2 is 1.25 MiB a core on the
// 2-vCPU Xeon VM), so a pass gathers a line per bucket and writes it whole, bypassing the cache
// (words scattered one by one to 2048 places each cost a read of their line first: 2M words take
// 66-72 ms plain against 37-45 gathered, 200k words 3.3 against 2.4 ms; the rebuilds of `bpx
// bench --backend sap --scene resting --sizes 1000000`). A line shared
// by several buckets (a bucket can be shorter than a line) is written whole by the last of them,
// garbage in the others' parts included; those parts are the others' tails, written at the end,
// so every word lands where the plain pass would put it.
static void radix_pass(const uint64_t *src, uint64_t *dst, uint32_t n, int shift, uint32_t *counts,
                       bpx_radix_work *work)
{
    const uint32_t mask = BPX_RADIX_BUCKETS - 1;
    if (n < BPX_RADIX_STREAM_WORDS || !work->lines) {
        for (uint32_t k = 0; k < n; k++) {
            uint64_t x = src[k];
            dst[counts[(x >> shift) & mask]++] = x;
        }
        return;
    }
    for (uint32_t k = 0; k < n; k++) {
        uint64_t x = src[k];
        uint32_t b = (uint32_t)(x >> shift) & mask;
        uint32_t at = counts[b]++;
        (*work->lines)[b][at % BPX_RADIX_LINE] = x;
        if (at % BPX_RADIX_LINE == BPX_RADIX_LINE - 1)
            put_line(dst + (at - (BPX_RADIX_LINE - 1)), (*work->lines)[b]);
    }
#if defined(__SSE2__)
    _mm_sfence(); // the streamed lines before the plain stores below, and before any reader
#endif
    uint32_t begin = 0; // each bucket's tail: its words after its last whole line
    for (uint32_t b = 0; b < BPX_RADIX_BUCKETS; b++) {
        uint32_t end = counts[b], line = end - end % BPX_RADIX_LINE;
        for (uint32_t at = line > begin ? line : begin; at < end; at++)
            dst[at] = (*work->lines)[b][at % BPX_RADIX_LINE];
        begin = end;
    }
}

void bpx__radix_sort_words(uint64_t *src, uint64_t *dst, uint32_t n, bpx_radix_work *work)
{
    memset(work->counts, 0, sizeof work->counts);
    for (uint32_t k = 0; k < n; k++) {
        uint32_t key = (uint32_t)(src[k] >> 32);
        for (int p = 0; p < BPX_RADIX_PASSES; p++)
            work->counts[p][(key >> (p * BPX_RADIX_BITS)) & (BPX_RADIX_BUCKETS - 1)]++;
    }
    int passes[BPX_RADIX_PASSES], count = 0; // the passes whose digit varies
    for (int p = 0; p < BPX_RADIX_PASSES; p++) {
        uint32_t *c = work->counts[p], sum = 0;
        bool varies = true;
        for (uint32_t b = 0; b < BPX_RADIX_BUCKETS; b++) {
            varies &= c[b] != n;
            uint32_t t = c[b];
            c[b] = sum;
            sum += t;
        }
        if (varies && n > 1)
            passes[count++] = p;
    }
    uint64_t *from = src, *to = dst; // odd pass counts end in dst, even ones are copied there
    for (int k = 0; k < count; k++) {
        radix_pass(from, to, n, 32 + passes[k] * BPX_RADIX_BITS, work->counts[passes[k]], work);
        uint64_t *t = from;
        from = to;
        to = t;
    }
    if (from != dst && n)
        memcpy(dst, from, n * sizeof *src);
}

bool bpx__insertion_sort(uint32_t *keys, uint32_t *ids, uint32_t n, uint64_t max_moves)
{
    uint64_t moves = 0;
    for (uint32_t k = 1; k < n; k++) {
        uint32_t key = keys[k], id = ids[k];
        uint32_t at = k;
        while (at > 0 && keys[at - 1] > key) {
            keys[at] = keys[at - 1];
            ids[at] = ids[at - 1];
            at--;
        }
        keys[at] = key;
        ids[at] = id;
        moves += k - at;
        if (moves > max_moves)
            return false;
    }
    return true;
}
