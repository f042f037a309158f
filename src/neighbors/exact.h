// Exact signs of small sums of doubles, for deciding a pair on its input coordinates: the
// float32 comparator only proposes candidates, and these say yes or no as real numbers would.
#pragma once

#include <math.h>

// s + e == a + b exactly (Knuth's two-sum; needs IEEE rounding, no fast-math).
static inline void bpx__two_sum(double a, double b, double *s, double *e)
{
    double sum = a + b;
    double bv = sum - a;
    double av = sum - bv;
    *e = (a - av) + (b - bv);
    *s = sum;
}

// The sign (-1, 0, 1) of t[0] + ... + t[k-1] as real numbers, k <= 6, every |t| below about
// 2^1004 (coordinates and the cutoff below 2^1000, a shift times a period a little more), so that
// no partial sum overflows. Fast path: the rounded sum, when it is farther from 0 than its error
// bound; otherwise Shewchuk's expansion sum, whose largest component carries the sign.
static inline int bpx__exact_sign(const double *t, int k)
{
    double sum = 0, magnitude = 0;
    for (int x = 0; x < k; x++) {
        sum += t[x];
        magnitude += fabs(t[x]);
    }
    if (fabs(sum) > magnitude * 0x1p-50) // k - 1 roundings of at most 2^-53 of the magnitude
        return sum > 0 ? 1 : -1;
    double e[6];
    int m = 0;
    for (int x = 0; x < k; x++) {
        double q = t[x];
        int h = 0;
        for (int y = 0; y < m; y++) {
            double s, err;
            bpx__two_sum(q, e[y], &s, &err);
            if (err != 0)
                e[h++] = err;
            q = s;
        }
        if (q != 0)
            e[h++] = q;
        m = h;
    }
    return m == 0 ? 0 : (e[m - 1] > 0 ? 1 : -1);
}
