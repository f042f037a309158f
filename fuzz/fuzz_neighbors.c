// Fuzzes bpx_find_neighbors: a cell, a cutoff, a metric, an input format and up to 40 objects
// decoded from the bytes. SPDX-License-Identifier: MIT
//
// Properties, besides no crash, leak or undefined behaviour:
// - the cell list (auto backend, points) and the image search (brute backend) return the same
//   status and, on success, the same bytes (pairs, shifts, distances), on 1 and 3 workers;
// - on success the pairs are exactly those of a brute force over every shift, written here:
//   coordinates, periods and cutoffs are multiples of 1/8 below 2^8, where double arithmetic is
//   exact, so the two must agree bit for bit;
// - an error leaves the list empty and names itself in the message;
// - points (Euclidean) in a triclinic cell sheared from the periods: exactly a brute force's
//   pairs, shifts and distances over every image, on 1 and 3 workers (check_triclinic).
#include <math.h>
#include <stdint.h>
#include <string.h>

#include <bpx/bpx.h>

#include "fuzz_check.h"

enum { MAX_OBJECTS = 40 };

typedef struct input {
    bpx_neighbor_def def;
    uint32_t n;
    double lo[MAX_OBJECTS][3], hi[MAX_OBJECTS][3];
    union {
        bpx_box f32[MAX_OBJECTS];
        bpx_box64 f64[MAX_OBJECTS];
        float p32[3 * MAX_OBJECTS];
        double p64[3 * MAX_OBJECTS];
    } data;
} input;

static uint8_t take(const uint8_t **bytes, size_t *size)
{
    if (*size == 0)
        return 0;
    (*size)--;
    return *(*bytes)++;
}

// A multiple of 1/8; the byte 255 gives a bad value (NaN, infinite or negative) now and then.
static double eighths(uint8_t b, double lo)
{
    if (b == 255)
        return NAN;
    if (b == 254)
        return -1;
    return lo + b / 8.0;
}

static void decode(const uint8_t *bytes, size_t size, input *in)
{
    memset(in, 0, sizeof *in);
    in->def = bpx_default_neighbor_def();
    uint8_t flags = take(&bytes, &size);
    in->def.format = (bpx_input_format)(flags & 3);
    in->def.metric = (bpx_metric)(flags >> 2 & 1);
    for (int a = 0; a < 3; a++) // periods 1 .. 32.75 on the axes the flags make periodic
        in->def.period[a] = flags >> (3 + a) & 1 ? eighths(take(&bytes, &size) % 253, 1) : 0;
    in->def.cutoff = eighths(take(&bytes, &size), 0) / 16; // 0 .. 2, or bad
    in->def.want_distances = true;
    bool points = in->def.format == BPX_POINTS_F32 || in->def.format == BPX_POINTS_F64;
    while (size >= (points ? 3u : 6u) && in->n < MAX_OBJECTS) {
        uint32_t k = in->n++;
        for (int a = 0; a < 3; a++) {
            in->lo[k][a] = (int8_t)take(&bytes, &size) / 8.0; // -16 .. 15.875
            in->hi[k][a] = points ? in->lo[k][a] : in->lo[k][a] + take(&bytes, &size) / 128.0;
        }
    }
    for (uint32_t k = 0; k < in->n; k++)
        for (int a = 0; a < 3; a++)
            switch (in->def.format) {
            case BPX_BOXES_F32:
                in->data.f32[k].min[a] = (float)in->lo[k][a];
                in->data.f32[k].max[a] = (float)in->hi[k][a];
                break;
            case BPX_BOXES_F64:
                in->data.f64[k].min[a] = in->lo[k][a];
                in->data.f64[k].max[a] = in->hi[k][a];
                break;
            case BPX_POINTS_F32:
                in->data.p32[3 * k + a] = (float)in->lo[k][a];
                break;
            default:
                in->data.p64[3 * k + a] = in->lo[k][a];
            }
}

// The number of (i <= j, shift) pairs within the cutoff, and whether `list` holds exactly them
// in order with these distances.
static bool matches_brute_force(const input *in, const bpx_neighbor_list *list)
{
    const double *L = in->def.period;
    double c = in->def.cutoff;
    size_t at = 0;
    for (uint32_t i = 0; i < in->n; i++)
        for (uint32_t j = i; j < in->n; j++) {
            int32_t first[3], last[3], s[3];
            for (int a = 0; a < 3; a++) {
                first[a] = L[a] > 0 ? (int32_t)floor((in->lo[i][a] - in->hi[j][a] - c) / L[a]) - 1 : 0;
                last[a] = L[a] > 0 ? (int32_t)ceil((in->hi[i][a] - in->lo[j][a] + c) / L[a]) + 1 : 0;
            }
            for (s[0] = first[0]; s[0] <= last[0]; s[0]++)
                for (s[1] = first[1]; s[1] <= last[1]; s[1]++)
                    for (s[2] = first[2]; s[2] <= last[2]; s[2]++) {
                        if (i == j && (s[0] ? s[0] : s[1] ? s[1] : s[2]) <= 0)
                            continue;
                        double far = -INFINITY, squares = 0;
                        for (int a = 0; a < 3; a++) {
                            double gap = fmax(in->lo[j][a] + s[a] * L[a] - in->hi[i][a],
                                              in->lo[i][a] - in->hi[j][a] - s[a] * L[a]);
                            far = fmax(far, gap);
                            squares += gap > 0 ? gap * gap : 0;
                        }
                        bool in_reach = in->def.metric == BPX_METRIC_BOX ? far <= c
                                                                         : squares <= c * c;
                        if (!in_reach)
                            continue;
                        double d = in->def.metric == BPX_METRIC_BOX ? fmax(far, 0) : sqrt(squares);
                        if (at >= list->count)
                            return false;
                        const bpx_image_pair *p = &list->pairs[at];
                        if (p->i != i || p->j != j || memcmp(p->shift, s, sizeof s) != 0 ||
                            list->distances[at] != d)
                            return false;
                        at++;
                    }
        }
    return at == list->count;
}

// The same points in a triclinic cell sheared from the periods (tilts of k/4 of a vector's
// length, k from the input; an axis without a period is an open axis, its vector a unit):
// every (i <= j, S) with |x_j + S H - x_i| <= cutoff, in the order and with the arithmetic of
// the header (p = S_0 a + S_1 b + S_2 c, (x_j + p) - x_i), bit for bit, at 1 and 3 workers.
// Multiples of 1/32 throughout: no gap is small enough for bpx's rescaling.
static void check_triclinic(const input *in)
{
    const double *L = in->def.period;
    double c = in->def.cutoff;
    if ((in->def.format != BPX_POINTS_F32 && in->def.format != BPX_POINTS_F64) ||
        in->def.metric != BPX_METRIC_EUCLIDEAN || !(c >= 0) || (!L[0] && !L[1] && !L[2]))
        return;
    uint32_t h = (in->n + 1) * 2654435761u;
    for (uint32_t k = 0; k < in->n; k++)
        h = (h ^ (uint32_t)(int32_t)(in->lo[k][0] * 8)) * 16777619u;
    int k1 = (int)(h >> 4 & 7) - 4, k2 = (int)(h >> 8 & 7) - 4, k3 = (int)(h >> 12 & 7) - 4;
    double side[3];
    for (int a = 0; a < 3; a++)
        side[a] = L[a] > 0 ? L[a] : 1;
    double H[3][3] = {{side[0], 0, 0},
                      {k1 * side[0] / 4, side[1], 0},
                      {k2 * side[0] / 4, k3 * side[1] / 4, side[2]}};
    // H^-1 (lower triangular): s_a = sum_c x_c G[c][a]; only for the shifts' range
    double G[3][3] = {{1 / H[0][0], 0, 0}, {0, 1 / H[1][1], 0}, {0, 0, 1 / H[2][2]}};
    G[1][0] = -H[1][0] * G[0][0] / H[1][1];
    G[2][1] = -H[2][1] * G[1][1] / H[2][2];
    G[2][0] = -(H[2][0] * G[0][0] + H[2][1] * G[1][0]) / H[2][2];
    bpx_neighbor_def def = bpx_default_neighbor_def();
    def.format = in->def.format;
    def.metric = BPX_METRIC_EUCLIDEAN;
    def.cutoff = c;
    def.want_distances = true;
    memcpy(def.cell, H, sizeof H);
    for (int a = 0; a < 3; a++)
        def.cell_open[a] = !(L[a] > 0);
    bpx_neighbor_list lists[2];
    for (int run = 0; run < 2; run++) {
        def.worker_count = run ? 3 : 1;
        bpx_error err;
        bpx_status status = bpx_find_neighbors(&def, &in->data, in->n, &lists[run], &err);
        FUZZ_CHECK(status == BPX_OK, "triclinic (k %d %d %d): %s: %s", k1, k2, k3,
                   bpx_status_name(status), err.message);
    }
    FUZZ_CHECK(lists[0].count == lists[1].count &&
                   (lists[0].count == 0 ||
                    (memcmp(lists[0].pairs, lists[1].pairs,
                            lists[0].count * sizeof *lists[0].pairs) == 0 &&
                     memcmp(lists[0].distances, lists[1].distances,
                            lists[0].count * sizeof *lists[0].distances) == 0)),
               "triclinic: 3 workers differ from 1");
    const bpx_neighbor_list *list = &lists[0];
    size_t at = 0;
    bool same = true;
    for (uint32_t i = 0; i < in->n && same; i++)
        for (uint32_t j = i; j < in->n && same; j++) {
            int32_t first[3], last[3], S[3];
            for (int a = 0; a < 3; a++) {
                double d = 0, reach = c * sqrt(G[0][a] * G[0][a] + G[1][a] * G[1][a] +
                                               G[2][a] * G[2][a]);
                for (int x = 0; x < 3; x++)
                    d += (in->lo[i][x] - in->lo[j][x]) * G[x][a];
                first[a] = L[a] > 0 ? (int32_t)floor(d - reach) - 2 : 0;
                last[a] = L[a] > 0 ? (int32_t)ceil(d + reach) + 2 : 0;
            }
            for (S[0] = first[0]; S[0] <= last[0]; S[0]++)
                for (S[1] = first[1]; S[1] <= last[1]; S[1]++)
                    for (S[2] = first[2]; S[2] <= last[2]; S[2]++) {
                        if (i == j && (S[0] ? S[0] : S[1] ? S[1] : S[2]) <= 0)
                            continue;
                        double g[3];
                        for (int x = 0; x < 3; x++) {
                            double p = (double)S[0] * H[0][x] + (double)S[1] * H[1][x] +
                                       (double)S[2] * H[2][x];
                            g[x] = fabs((in->lo[j][x] + p) - in->lo[i][x]);
                        }
                        double squares = g[0] * g[0] + g[1] * g[1] + g[2] * g[2];
                        if (fmax(g[0], fmax(g[1], g[2])) > c || !(squares <= c * c))
                            continue;
                        const bpx_image_pair *q = at < list->count ? &list->pairs[at] : NULL;
                        same = q && q->i == i && q->j == j &&
                               memcmp(q->shift, S, sizeof S) == 0 &&
                               list->distances[at] == sqrt(squares);
                        at++;
                    }
        }
    FUZZ_CHECK(same && at == list->count,
               "triclinic (k %d %d %d): %zu pairs, not the brute force's (n %u, cutoff %g)", k1,
               k2, k3, list->count, in->n, c);
    bpx_neighbor_list_free(&lists[0]);
    bpx_neighbor_list_free(&lists[1]);
}

int LLVMFuzzerTestOneInput(const uint8_t *bytes, size_t size);
int LLVMFuzzerTestOneInput(const uint8_t *bytes, size_t size)
{
    static input in;
    decode(bytes, size, &in);
    bpx_neighbor_list first = {0};
    bpx_status first_status = BPX_OK;
    static const bpx_backend backends[2] = {BPX_BACKEND_AUTO, BPX_BACKEND_BRUTE};
    for (int run = 0; run < 4; run++) {
        in.def.backend = backends[run & 1];
        in.def.worker_count = run < 2 ? 1 : 3;
        bpx_neighbor_list list;
        bpx_error err;
        bpx_status status = bpx_find_neighbors(&in.def, &in.data, in.n, &list, &err);
        if (status != BPX_OK) {
            FUZZ_CHECK(list.count == 0 && list.pairs == NULL, "an error left pairs");
            FUZZ_CHECK(err.status == status && err.message[0] != '\0', "no message for %s",
                       bpx_status_name(status));
        }
        if (run == 0) {
            first = list;
            first_status = status;
            if (status == BPX_OK)
                FUZZ_CHECK(matches_brute_force(&in, &list),
                           "%zu pairs, not the brute force's (n %u, cutoff %g, metric %d)",
                           list.count, in.n, in.def.cutoff, (int)in.def.metric);
            continue;
        }
        FUZZ_CHECK(status == first_status, "run %d: %s, run 0: %s", run, bpx_status_name(status),
                   bpx_status_name(first_status));
        FUZZ_CHECK(list.count == first.count &&
                       (list.count == 0 ||
                        (memcmp(list.pairs, first.pairs, list.count * sizeof *list.pairs) == 0 &&
                         memcmp(list.distances, first.distances,
                                list.count * sizeof *list.distances) == 0)),
                   "run %d: %zu pairs differ from run 0's %zu", run, list.count, first.count);
        bpx_neighbor_list_free(&list);
    }
    bpx_neighbor_list_free(&first);
    check_triclinic(&in);
    return 0;
}
