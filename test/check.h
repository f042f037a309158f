// bpx tests: a tiny shared harness. SPDX-License-Identifier: MIT
//
// CHECK(cond) records a failure (file:line, the expression, the current seed and context) and
// carries on, so one run shows every failure. main() ends with `return check_finish(...)`.
#pragma once

#include <inttypes.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <bpx/bpx.h>

/// ctest's skip code (SKIP_RETURN_CODE 77 on every test).
#define CHECK_SKIP 77

/// BPX_TEST_QUICK set (the tsan preset): the tests that sweep every SIMD width and worker count
/// keep the configurations that run threads, at the default width. ThreadSanitizer looks for
/// races between threads, which the other widths do not change, and runs 5 to 15 times slower.
static inline int check_quick(void)
{
    const char *quick = getenv("BPX_TEST_QUICK");
    return quick != NULL && *quick != '\0' && *quick != '0';
}

static int check_failures;
static int check_count;
static uint64_t check_seed;
static char check_context[256];

// Printing stops after this many failures in all, or per CHECK line; the count goes on.
#define CHECK_MAX_PRINTED 200
#define CHECK_MAX_PRINTED_PER_LINE 4

static struct {
    const char *file;
    int line;
    int count;
} check_lines[128];

static inline void check_set_seed(uint64_t seed)
{
    check_seed = seed;
}

/// What is being tested now ("dense n=100 backend=brute simd=avx2 workers=3"), for failures.
static inline void check_set_context(const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(check_context, sizeof check_context, fmt, ap);
    va_end(ap);
}

// How many times this CHECK line has failed, this one included.
static inline int check_line_failures(const char *file, int line)
{
    size_t slots = sizeof check_lines / sizeof check_lines[0];
    for (size_t k = 0; k < slots; k++) {
        if (!check_lines[k].file) {
            check_lines[k].file = file;
            check_lines[k].line = line;
        }
        if (check_lines[k].line == line && strcmp(check_lines[k].file, file) == 0) {
            return ++check_lines[k].count;
        }
    }
    return 1;
}

static inline void check_fail(const char *file, int line, const char *expr, const char *detail)
{
    check_failures++;
    int same_line = check_line_failures(file, line);
    if (check_failures <= CHECK_MAX_PRINTED && same_line <= CHECK_MAX_PRINTED_PER_LINE) {
        fprintf(stderr, "%s:%d: CHECK failed: %s%s%s [seed=%" PRIu64 "] [%s]\n", file, line, expr,
                detail[0] ? " -- " : "", detail, check_seed, check_context);
    } else if (same_line == CHECK_MAX_PRINTED_PER_LINE + 1) {
        fprintf(stderr, "%s:%d: (further failures of this check counted, not printed)\n", file,
                line);
    }
}

static inline const char *check_status_name(bpx_status s)
{
    const char *name = bpx_status_name(s);
    return name ? name : "(null)";
}

#define CHECK(cond)                                                                                \
    do {                                                                                           \
        check_count++;                                                                             \
        if (!(cond)) {                                                                             \
            check_fail(__FILE__, __LINE__, #cond, "");                                             \
        }                                                                                          \
    } while (0)

/// Like CHECK, with a printf-style detail on failure.
#define CHECK_MSG(cond, ...)                                                                       \
    do {                                                                                           \
        check_count++;                                                                             \
        if (!(cond)) {                                                                             \
            char check_detail_[256];                                                               \
            snprintf(check_detail_, sizeof check_detail_, __VA_ARGS__);                            \
            check_fail(__FILE__, __LINE__, #cond, check_detail_);                                  \
        }                                                                                          \
    } while (0)

/// Evaluates expr once and checks that it returned the wanted bpx_status.
#define CHECK_STATUS(expr, want)                                                                   \
    do {                                                                                           \
        bpx_status check_got_ = (expr);                                                            \
        bpx_status check_want_ = (want);                                                           \
        check_count++;                                                                             \
        if (check_got_ != check_want_) {                                                           \
            char check_detail_[160];                                                               \
            snprintf(check_detail_, sizeof check_detail_, "got %s, want %s",                      \
                     check_status_name(check_got_), check_status_name(check_want_));               \
            check_fail(__FILE__, __LINE__, #expr, check_detail_);                                  \
        }                                                                                          \
    } while (0)

#define CHECK_EQ_U64(a, b)                                                                         \
    do {                                                                                           \
        uint64_t check_a_ = (uint64_t)(a);                                                         \
        uint64_t check_b_ = (uint64_t)(b);                                                         \
        check_count++;                                                                             \
        if (check_a_ != check_b_) {                                                                \
            char check_detail_[96];                                                                \
            snprintf(check_detail_, sizeof check_detail_, "%" PRIu64 " != %" PRIu64, check_a_,   \
                     check_b_);                                                                    \
            check_fail(__FILE__, __LINE__, #a " == " #b, check_detail_);                           \
        }                                                                                          \
    } while (0)

/// Ends a test: prints a summary, returns the process exit code (0 pass, 1 fail, 77 skip).
static inline int check_finish(const char *name, int ran_anything)
{
    if (check_failures) {
        fprintf(stderr, "%s: FAILED, %d of %d checks\n", name, check_failures, check_count);
        return 1;
    }
    if (!ran_anything) {
        printf("%s: SKIPPED (nothing can run on this machine)\n", name);
        return CHECK_SKIP;
    }
    printf("%s: ok, %d checks\n", name, check_count);
    return 0;
}

/// malloc that aborts the test on failure: tests only allocate what they need.
static inline void *check_alloc(size_t size)
{
    void *p = malloc(size ? size : 1);
    if (!p) {
        fprintf(stderr, "test: out of memory (%zu bytes)\n", size);
        exit(2);
    }
    return p;
}

/// FNV-1a 64 over bytes.
static inline uint64_t check_fnv1a(const void *data, size_t size)
{
    const unsigned char *p = (const unsigned char *)data; // a cast for C++ includers
    uint64_t h = 0xcbf29ce484222325ull;
    for (size_t k = 0; k < size; k++) {
        h ^= p[k];
        h *= 0x100000001b3ull;
    }
    return h;
}

/// Backends whose kernels come in one build per SIMD width (bpx_world_def.simd selects it):
/// tests run them at every width the machine has.
static inline bool check_backend_has_simd(bpx_backend backend)
{
    return backend == BPX_BACKEND_BRUTE || backend == BPX_BACKEND_PRUNE ||
           backend == BPX_BACKEND_SAP; // sap's rebuild sweeps with the prune kernel
}

/// Most boxes a backend takes: every backend any count but rtl (the chip's RAMs). Suites skip
/// a backend at sizes beyond it (test_errors checks the refusal).
static inline uint32_t check_backend_max_boxes(bpx_backend backend)
{
    return backend == BPX_BACKEND_RTL ? BPX_RTL_MAX_BOXES : UINT32_MAX;
}
