// What the running CPU (and OS) can execute, detected once.
#pragma once

#include <stdbool.h>

#include "bpx/types.h"

/// Whether the CPU and OS support the instruction set (not whether the build has it).
bool bpx__cpu_supports(bpx_simd simd);
