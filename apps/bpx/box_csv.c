// bpx command-line tool: reads boxes from CSV text (see box_csv.h for the format).
// SPDX-License-Identifier: MIT
#include "box_csv.h"

#include <errno.h>
#include <math.h>
#include <stdarg.h>
#include <stdbool.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

enum {
    FIELD_COUNT = 6,
    READ_CHUNK = 1 << 16, // first buffer size; grows only for longer lines
    QUOTE_MAX = 40,       // longest field text echoed in a message
};

static const char *const field_names[FIELD_COUNT] = {
    "min x", "min y", "min z", "max x", "max y", "max z",
};

static const char axis_names[3] = {'x', 'y', 'z'};

void box_array_free(box_array *boxes)
{
    free(boxes->data);
    boxes->data = NULL;
    boxes->count = 0;
    boxes->capacity = 0;
}

static bool box_array_push(box_array *boxes, const bpx_box *box)
{
    if (boxes->count == boxes->capacity) {
        size_t capacity = boxes->capacity ? boxes->capacity * 2 : 1024;
        if (capacity > SIZE_MAX / sizeof(bpx_box)) {
            return false;
        }
        bpx_box *data = realloc(boxes->data, capacity * sizeof(bpx_box));
        if (data == NULL) {
            return false;
        }
        boxes->data = data;
        boxes->capacity = capacity;
    }
    boxes->data[boxes->count++] = *box;
    return true;
}

// Hands out NUL-terminated lines of a stream without a length limit (no getline in C11).
typedef struct line_reader {
    FILE *in;
    char *buf;
    size_t capacity; // bytes allocated (> 0); one is always kept free for a terminating NUL
    size_t begin;    // first unread byte
    size_t end;      // end of the bytes read so far
    bool eof;
} line_reader;

typedef enum read_result { READ_LINE, READ_END, READ_IO_ERROR, READ_NO_MEMORY } read_result;

// On READ_LINE, *line points into the reader's buffer (newline replaced by NUL) until the next
// call, and *length excludes the newline.
static read_result next_line(line_reader *r, char **line, size_t *length)
{
    for (;;) {
        char *start = r->buf + r->begin;
        char *newline = memchr(start, '\n', r->end - r->begin);
        if (newline != NULL) {
            *newline = '\0';
            *line = start;
            *length = (size_t)(newline - start);
            r->begin = (size_t)(newline + 1 - r->buf);
            return READ_LINE;
        }
        if (r->eof) {
            if (r->begin == r->end) {
                return READ_END;
            }
            r->buf[r->end] = '\0'; // last line without a newline; the spare byte holds the NUL
            *line = start;
            *length = r->end - r->begin;
            r->begin = r->end;
            return READ_LINE;
        }
        // Keep the partial line at the front, grow if it fills the buffer, then read more.
        if (r->begin > 0) {
            memmove(r->buf, r->buf + r->begin, r->end - r->begin);
            r->end -= r->begin;
            r->begin = 0;
        }
        if (r->capacity - r->end < 2) {
            size_t capacity = r->capacity * 2;
            char *buf = capacity > r->capacity ? realloc(r->buf, capacity) : NULL;
            if (buf == NULL) {
                return READ_NO_MEMORY;
            }
            r->buf = buf;
            r->capacity = capacity;
        }
        size_t got = fread(r->buf + r->end, 1, r->capacity - r->end - 1, r->in);
        r->end += got;
        if (ferror(r->in)) {
            return READ_IO_ERROR;
        }
        if (feof(r->in)) {
            r->eof = true;
        }
    }
}

static bool is_blank(char c)
{
    return c == ' ' || c == '\t' || c == '\r' || c == '\v' || c == '\f';
}

// Field text [begin, end) with surrounding blanks removed.
static void trim(char **begin, char **end)
{
    while (*begin < *end && is_blank(**begin)) {
        (*begin)++;
    }
    while (*end > *begin && is_blank((*end)[-1])) {
        (*end)--;
    }
}

typedef struct parse_context {
    const char *name;
    size_t line_number;
    char *message;
    size_t message_size;
} parse_context;

#if defined(__GNUC__)
#define BOX_CSV_PRINTF __attribute__((format(printf, 2, 3)))
#else
#define BOX_CSV_PRINTF
#endif

// Writes "NAME:LINE: " and the formatted detail into the message; returns -1.
static int fail_at(const parse_context *ctx, const char *fmt, ...) BOX_CSV_PRINTF;

static int fail_at(const parse_context *ctx, const char *fmt, ...)
{
    int used = snprintf(ctx->message, ctx->message_size, "%s:%zu: ", ctx->name, ctx->line_number);
    if (used >= 0 && (size_t)used < ctx->message_size) {
        va_list args;
        va_start(args, fmt);
        vsnprintf(ctx->message + used, ctx->message_size - (size_t)used, fmt, args);
        va_end(args);
    }
    return -1;
}

static int quote_length(const char *begin, const char *end)
{
    size_t length = (size_t)(end - begin);
    return length > QUOTE_MAX ? QUOTE_MAX : (int)length;
}

static const char *quote_ellipsis(const char *begin, const char *end)
{
    return (size_t)(end - begin) > QUOTE_MAX ? "..." : "";
}

// Parses one field [begin, end) (already trimmed) as a finite float.
static int parse_field(const parse_context *ctx, int field, const char *begin, const char *end,
                       float *out)
{
    const char *label = field_names[field];
    if (begin == end) {
        return fail_at(ctx, "field %d (%s): empty", field + 1, label);
    }
    int shown = quote_length(begin, end);
    const char *more = quote_ellipsis(begin, end);
    // The caller NUL-terminated the field, so strtof cannot run into the next one.
    char *stop;
    errno = 0;
    float value = strtof(begin, &stop);
    if (stop != end) {
        return fail_at(ctx, "field %d (%s): not a number: \"%.*s%s\"", field + 1, label, shown,
                       begin, more);
    }
    if (isinf(value) && errno == ERANGE) {
        return fail_at(ctx, "field %d (%s): out of float range: \"%.*s%s\"", field + 1, label,
                       shown, begin, more);
    }
    if (!isfinite(value)) {
        return fail_at(ctx, "field %d (%s): not finite: \"%.*s%s\"", field + 1, label, shown,
                       begin, more);
    }
    *out = value;
    return 0;
}

// Parses one line. Returns 1 with *box set, 0 for a blank or comment-only line, -1 on error.
static int parse_line(const parse_context *ctx, char *line, size_t length, bpx_box *box)
{
    if (memchr(line, '\0', length) != NULL) {
        return fail_at(ctx, "contains a NUL byte");
    }
    char *comment = strchr(line, '#');
    if (comment != NULL) {
        *comment = '\0';
        length = (size_t)(comment - line);
    }
    char *begin = line;
    char *end = line + length;
    trim(&begin, &end);
    if (begin == end) {
        return 0;
    }

    // Split first, so a wrong field count is reported as such rather than as a bad number.
    char *field_begin[FIELD_COUNT];
    char *field_end[FIELD_COUNT];
    int fields = 0;
    char *p = begin;
    for (;;) {
        char *comma = memchr(p, ',', (size_t)(end - p));
        char *stop = comma != NULL ? comma : end;
        if (fields < FIELD_COUNT) {
            field_begin[fields] = p;
            field_end[fields] = stop;
        }
        fields++;
        if (comma == NULL) {
            break;
        }
        p = comma + 1;
    }
    if (fields != FIELD_COUNT) {
        return fail_at(ctx,
                       "expected 6 comma-separated fields (min x, min y, min z, max x, max y, "
                       "max z), found %d",
                       fields);
    }

    float values[FIELD_COUNT];
    for (int f = 0; f < FIELD_COUNT; f++) {
        trim(&field_begin[f], &field_end[f]);
        // Terminate the field so strtof stops at its end; restored for the messages below.
        char saved = *field_end[f];
        *field_end[f] = '\0';
        int status = parse_field(ctx, f, field_begin[f], field_end[f], &values[f]);
        *field_end[f] = saved;
        if (status != 0) {
            return status;
        }
    }
    for (int axis = 0; axis < 3; axis++) {
        if (values[axis] > values[axis + 3]) {
            const char *min_b = field_begin[axis], *min_e = field_end[axis];
            const char *max_b = field_begin[axis + 3], *max_e = field_end[axis + 3];
            return fail_at(ctx, "min %c (%.*s%s) > max %c (%.*s%s)", axis_names[axis],
                           quote_length(min_b, min_e), min_b, quote_ellipsis(min_b, min_e),
                           axis_names[axis], quote_length(max_b, max_e), max_b,
                           quote_ellipsis(max_b, max_e));
        }
        box->min[axis] = values[axis];
        box->max[axis] = values[axis + 3];
    }
    return 1;
}

int box_csv_read(FILE *in, const char *name, box_array *boxes, char *message,
                 size_t message_size)
{
    parse_context ctx = {name, 0, message, message_size};
    // Allocated up front: memchr and pointer arithmetic need a real buffer even when empty.
    line_reader reader = {in, malloc(READ_CHUNK), READ_CHUNK, 0, 0, false};
    if (reader.buf == NULL) {
        snprintf(message, message_size, "%s: out of memory", name);
        return -1;
    }
    int status = 0;
    for (;;) {
        char *line;
        size_t length;
        read_result result = next_line(&reader, &line, &length);
        if (result == READ_END) {
            break;
        }
        if (result == READ_IO_ERROR) {
            snprintf(message, message_size, "%s: read error: %s", name, strerror(errno));
            status = -1;
            break;
        }
        if (result == READ_NO_MEMORY) {
            snprintf(message, message_size, "%s:%zu: out of memory (line too long)", name,
                     ctx.line_number + 1);
            status = -1;
            break;
        }
        ctx.line_number++;
        // A UTF-8 byte-order mark opens files saved as Excel's "CSV UTF-8"; it is no data.
        if (ctx.line_number == 1 && length >= 3 && memcmp(line, "\xEF\xBB\xBF", 3) == 0) {
            line += 3;
            length -= 3;
        }
        bpx_box box;
        int parsed = parse_line(&ctx, line, length, &box);
        if (parsed < 0) {
            status = -1;
            break;
        }
        if (parsed == 0) {
            continue;
        }
        if (boxes->count >= BPX_MAX_BOXES) {
            status = fail_at(&ctx, "too many boxes (at most %u)", (unsigned)BPX_MAX_BOXES);
            break;
        }
        if (!box_array_push(boxes, &box)) {
            status = fail_at(&ctx, "out of memory after %zu boxes", boxes->count);
            break;
        }
    }
    free(reader.buf);
    return status;
}
