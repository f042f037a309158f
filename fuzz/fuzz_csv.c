// Fuzzes the CSV box reader of `bpx pairs` (apps/bpx/box_csv.c) with arbitrary bytes.
// SPDX-License-Identifier: MIT
//
// Properties, besides no crash, leak or undefined behaviour:
// - success: every box is valid for bpx (finite, min <= max), and writing the boxes back as
//   CSV ("%.9g", which round-trips binary32) and reading that again gives the same bits;
// - error: the message is one non-empty line that starts with the input's name.
#define _POSIX_C_SOURCE 200809L
#include <math.h>
#include <stdint.h>
#include <string.h>

#include "box_csv.h"
#include "fuzz_check.h"

static void check_valid(const box_array *boxes)
{
    for (size_t i = 0; i < boxes->count; i++)
        for (int a = 0; a < 3; a++) {
            float lo = boxes->data[i].min[a], hi = boxes->data[i].max[a];
            FUZZ_CHECK(isfinite(lo) && isfinite(hi) && lo <= hi, "box %zu axis %d: %g %g", i, a,
                       (double)lo, (double)hi);
        }
}

static void check_message(const char *message)
{
    FUZZ_CHECK(strncmp(message, "input", 5) == 0, "message \"%s\" does not name the input",
               message);
    FUZZ_CHECK(strchr(message, '\n') == NULL, "message \"%s\" spans lines", message);
}

// Writes the boxes as CSV and reads them back: the reader must give back the same bits.
static void check_round_trip(const box_array *boxes)
{
    char *text = NULL;
    size_t size = 0;
    FILE *out = open_memstream(&text, &size);
    FUZZ_CHECK(out != NULL, "open_memstream failed");
    for (size_t i = 0; i < boxes->count; i++) {
        const bpx_box *b = &boxes->data[i];
        fprintf(out, "%.9g, %.9g, %.9g, %.9g, %.9g, %.9g\n", (double)b->min[0], (double)b->min[1],
                (double)b->min[2], (double)b->max[0], (double)b->max[1], (double)b->max[2]);
    }
    fclose(out);
    FILE *in = fmemopen(text, size ? size : 1, "r");
    FUZZ_CHECK(in != NULL, "fmemopen failed");
    if (size == 0)
        fgetc(in); // an empty memstream: read its one NUL byte away, so the reader sees EOF
    box_array again = {0};
    char message[256] = "";
    int status = box_csv_read(in, "again", &again, message, sizeof message);
    fclose(in);
    FUZZ_CHECK(status == 0, "re-reading the written boxes failed: %s", message);
    FUZZ_CHECK(again.count == boxes->count, "%zu boxes read back, %zu written", again.count,
               boxes->count);
    FUZZ_CHECK(again.count == 0 ||
                   memcmp(again.data, boxes->data, again.count * sizeof(bpx_box)) == 0,
               "boxes read back differ from those written");
    box_array_free(&again);
    free(text);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    // fmemopen needs a non-empty buffer; an empty input is a copy of one byte read away.
    char *copy = malloc(size + 1);
    if (!copy)
        return 0;
    if (size)
        memcpy(copy, data, size);
    FILE *in = fmemopen(copy, size ? size : 1, "r");
    if (!in) {
        free(copy);
        return 0;
    }
    if (size == 0)
        fgetc(in);
    box_array boxes = {0};
    char message[256];
    memset(message, 'x', sizeof message);
    message[sizeof message - 1] = '\0';
    int status = box_csv_read(in, "input", &boxes, message, sizeof message);
    fclose(in);
    FUZZ_CHECK(status == 0 || status == -1, "status %d", status);
    if (status == 0) {
        check_valid(&boxes);
        check_round_trip(&boxes);
    } else {
        check_message(message);
    }
    box_array_free(&boxes);
    free(copy);
    return 0;
}
