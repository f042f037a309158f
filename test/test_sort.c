// The radix sort of src/cpu/sort.c that sap's rebuilds use (bpx__radix_sort_words), against a
// plain stable sort: sizes on both sides of the streamed path (1 MiB of words), keys over the
// whole 32 bits, few distinct keys, one key, and keys that differ in one digit only (one or two
// passes skipped, so the result takes the other buffer's way home). The low halves carry each
// word's first place, scrambled, so that a sort that is not stable shows.
#include "check.h"
#include "core/alloc.h"
#include "cpu/sort.h"

static uint64_t rng_state = 0x9e3779b97f4a7c15ull;

static uint32_t next_u32(void)
{
    rng_state ^= rng_state << 13;
    rng_state ^= rng_state >> 7;
    rng_state ^= rng_state << 17;
    return (uint32_t)(rng_state >> 16);
}

typedef enum {
    KEYS_ANY,
    KEYS_FEW,
    KEYS_ONE,
    KEYS_LOW_DIGIT,
    KEYS_OUTER_DIGITS,
    KEY_KINDS
} key_kind;

static const char *const kind_names[KEY_KINDS] = {"any", "few", "one", "low digit", "outer digits"};

static uint32_t make_key(key_kind kind)
{
    switch (kind) {
    case KEYS_ANY:
        return next_u32();
    case KEYS_FEW:
        return 0x40000000u + (next_u32() % 5) * 0x01010101u;
    case KEYS_ONE:
        return 0x3f800000u;
    case KEYS_LOW_DIGIT: // one pass (the 2nd and 3rd digits are the same everywhere)
        return 0x12345000u | (next_u32() & 0x7ffu);
    default: // two passes (the 2nd digit is the same): an even count, copied home
        return 0x00123800u | (next_u32() & 0xffc007ffu);
    }
}

// A stable insertion sort by key would take minutes at these sizes: a merge sort.
static void merge_sort(uint64_t *a, uint64_t *tmp, size_t n)
{
    if (n < 2)
        return;
    size_t half = n / 2;
    merge_sort(a, tmp, half);
    merge_sort(a + half, tmp, n - half);
    size_t i = 0, j = half, k = 0;
    while (i < half && j < n)
        tmp[k++] = (a[j] >> 32) < (a[i] >> 32) ? a[j++] : a[i++];
    while (i < half)
        tmp[k++] = a[i++];
    while (j < n)
        tmp[k++] = a[j++];
    memcpy(a, tmp, n * sizeof *a);
}

static void test_size(uint32_t n, key_kind kind, bpx_radix_work *work, int streamed)
{
    check_set_context("n=%u keys=%s lines=%d", n, kind_names[kind], streamed);
    size_t bytes = (n ? n : 1) * sizeof(uint64_t);
    uint64_t *src = bpx__alloc(bytes), *dst = bpx__alloc(bytes);
    uint64_t *want = check_alloc(bytes), *tmp = check_alloc(bytes);
    CHECK(src && dst);
    if (!src || !dst)
        return;
    for (uint32_t k = 0; k < n; k++) {
        // Low half: the place, scrambled by an odd multiplier (a bijection), so equal keys keep
        // an order the sort must not change but that is not the order of the low halves.
        src[k] = (uint64_t)make_key(kind) << 32 | (uint32_t)(k * 2654435761u);
        want[k] = src[k];
    }
    merge_sort(want, tmp, n);
    bpx__radix_sort_words(src, dst, n, work);
    uint32_t wrong = 0;
    for (uint32_t k = 0; k < n; k++)
        wrong += dst[k] != want[k];
    CHECK_MSG(wrong == 0, "%u of %u words out of place", wrong, n);
    bpx__free(src, bytes);
    bpx__free(dst, bytes);
    free(want);
    free(tmp);
}

int main(void)
{
    bpx_radix_work *work = bpx__alloc(sizeof *work);
    bpx_radix_lines *lines = bpx__alloc(sizeof *lines);
    CHECK(work != NULL && lines != NULL);
    if (!work || !lines)
        return check_finish("test_sort", 1);
    // BPX_RADIX_STREAM_WORDS (131072) is the first size the streamed path takes; odd sizes leave
    // partial lines at every bucket's ends. Without lines, every size takes the plain path.
    const uint32_t sizes[] = {0, 1, 2, 7, 8, 9, 1000, 4097, 131071, 131072, 131073, 300007};
    for (int streamed = 0; streamed < 2; streamed++) {
        work->lines = streamed ? lines : NULL;
        for (size_t s = 0; s < sizeof sizes / sizeof sizes[0]; s++)
            for (int kind = 0; kind < KEY_KINDS; kind++)
                test_size(sizes[s], (key_kind)kind, work, streamed);
    }
    bpx__free(lines, sizeof *lines);
    bpx__free(work, sizeof *work);
    return check_finish("test_sort", 1);
}
