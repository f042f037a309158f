// bpx command-line tool: reads boxes from CSV text.
// SPDX-License-Identifier: MIT
//
// Format: one box per line, six numbers separated by commas (spaces and tabs allowed around
// them): min x, min y, min z, max x, max y, max z. '#' starts a comment running to the end of
// the line; blank lines are skipped; CRLF line ends and a UTF-8 byte-order mark at the start
// of the input are accepted. Every box is checked as the
// library would (finite, min <= max) so that errors can name the line, not just the box index.
#pragma once

#include <stddef.h>
#include <stdio.h>

#include <bpx/types.h>

// A growable array of boxes. Zero-initialise before use; release with box_array_free.
typedef struct box_array {
    bpx_box *data;
    size_t count;
    size_t capacity;
} box_array;

void box_array_free(box_array *boxes);

// Appends every box of `in` to *boxes. `name` names the input in messages ("boxes.csv").
// Returns 0 on success. On error returns -1, writes a one-line message without newline to
// message (e.g. `boxes.csv:17: field 4 (max x): not a number: "abc"`); *boxes then holds the
// boxes read so far and must still be freed.
int box_csv_read(FILE *in, const char *name, box_array *boxes, char *message,
                 size_t message_size);
