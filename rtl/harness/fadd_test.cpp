// bpx RTL: the binary32 adder (rtl/fadd.sv) against C's float + on this host (SSE: round to
// nearest even, no flush to zero), over classes of finite operands: random bits, subnormals,
// equal and adjacent exponents (cancellation), exponents far apart, values near FLT_MAX
// (overflow must set the flag and give infinity), signed zeros, and the updater's own case
// (centre + minimum, centre - minimum). Usage: fadd_test [count per class] [seed].
#include <cinttypes>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <random>

#include <verilated.h>

#include "Vfadd.h"

static float f_of(uint32_t u)
{
    float f;
    std::memcpy(&f, &u, 4);
    return f;
}
static uint32_t u_of(float f)
{
    uint32_t u;
    std::memcpy(&u, &f, 4);
    return u;
}

int main(int argc, char **argv)
{
    Verilated::commandArgs(argc, argv);
    const long count = argc > 1 ? std::atol(argv[1]) : 200000;
    std::mt19937 rng(argc > 2 ? (unsigned)std::atoi(argv[2]) : 1);
    VerilatedContext ctx;
    Vfadd top{&ctx};
    long checked = 0, bad = 0, overflows = 0;
    auto check = [&](uint32_t a, uint32_t b) {
        if ((a >> 23 & 0xff) == 0xff || (b >> 23 & 0xff) == 0xff)
            return;
        top.a = a;
        top.b = b;
        top.eval();
        volatile float fa = f_of(a), fb = f_of(b);
        float want = fa + fb;
        bool want_overflow = std::isinf(want);
        checked++;
        overflows += want_overflow;
        if (top.s != u_of(want) || (bool)top.overflow != want_overflow) {
            if (bad < 10)
                std::fprintf(stderr, "%08x + %08x: rtl %08x (overflow %d), C %08x\n", a, b, top.s,
                             top.overflow, u_of(want));
            bad++;
        }
    };
    auto any = [&]() { return (uint32_t)rng(); };
    auto with_exp = [&](uint32_t e) { return (rng() & 0x807fffffu) | (e & 0xff) << 23; };
    for (long k = 0; k < count; k++) {
        uint32_t a = any(), b = any();
        check(a, b);                                         // random bits
        check(a & 0x807fffffu, b & 0x807fffffu);             // subnormal + subnormal
        check(a & 0x807fffffu, with_exp(rng() % 4));         // subnormal + tiny normal
        uint32_t e = rng() % 255;
        check(with_exp(e), with_exp(e));                     // equal exponents: cancellation
        check(with_exp(e), with_exp(e ? e - 1 : 0));         // adjacent exponents
        check(with_exp(e), with_exp(e > 30 ? e - 20 - rng() % 12 : 0)); // far apart: sticky
        check(with_exp(253 + rng() % 2), with_exp(250 + rng() % 5)); // near FLT_MAX
        uint32_t c = with_exp(100 + rng() % 60), m = with_exp(100 + rng() % 60) | 0x80000000u;
        check(c, m);                                         // centre + minimum
        check(c, m ^ 0x80000000u);                           // centre - minimum
        check(a, a ^ 0x80000000u);                           // x + -x = +0
        check(a, a);                                         // doubling (overflow near the top)
    }
    for (uint32_t z : {0u, 0x80000000u})
        for (uint32_t w : {0u, 0x80000000u, 1u, 0x80000001u, 0x3f800000u})
            check(z, w), check(w, z);
    std::printf("fadd: %ld sums checked, %ld overflowed, %ld mismatches\n", checked, overflows, bad);
    return bad ? 1 : 0;
}
