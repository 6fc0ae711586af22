/* The bits of sin(x), cos(x) and pow(y, -0.2) for n pseudo-random x in [-a, a] and y in
 * (0, 2], one line per sample in hex: the same program built against two C libraries tells
 * where their results differ (tests/stewart_fmu/test_windows_fmu.py: glibc vs mingw-w64).
 *
 *   libm_probe N A */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static unsigned long long bits(double v) {
    uint64_t b;
    memcpy(&b, &v, sizeof b);
    return (unsigned long long)b;
}

int main(int argc, char **argv) {
    uint64_t s = 88172645463325252ull;   /* xorshift64: the same samples on every platform */
    long k, n;
    double a;
    if (argc != 3) {
        fprintf(stderr, "usage: libm_probe N A\n");
        return 2;
    }
    n = atol(argv[1]);
    a = atof(argv[2]);
    for (k = 0; k < n; k++) {
        double u, x, y;
        s ^= s << 13, s ^= s >> 7, s ^= s << 17;
        u = (double)(s >> 11) / 9007199254740992.0;   /* [0, 1) */
        x = a * (2.0 * u - 1.0);
        y = 2.0 * (1.0 - u);
        /* sin and cos of one x: GCC makes them one sincos call, as in the core's rotations.c */
        printf("%016llx %016llx %016llx\n", bits(sin(x)), bits(cos(x)), bits(pow(y, -0.2)));
    }
    return 0;
}
