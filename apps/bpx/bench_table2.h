// bpx bench --table2: the paper's Table 2 on the paper's scenario. SPDX-License-Identifier: MIT
#pragma once

#include <stdint.h>

/// Prints the table on stdout (progress on stderr). Returns 0, or -1 after printing the error.
int bench_table2(int threads, int cycles, uint64_t seed);
