#!/usr/bin/env sh
# Prints an OpenBLAS kernel (an OPENBLAS_CORETYPE value) that this CPU runs but that OpenBLAS
# would not pick by itself: the numerically sensitive tests are run again under it
# (`make test-numerics`), so a result that holds only for one order of BLAS additions shows.
# OpenBLAS picks the widest kernel the CPU has: SkylakeX with AVX-512, Haswell (or Zen) with
# AVX2, Sandybridge with AVX; one step narrower is always runnable and adds in another order.
flags=$(grep -m1 '^flags' /proc/cpuinfo 2>/dev/null)
has() { case " $flags " in *" $1 "*) return 0;; esac; return 1; }
if has avx512f; then kernel=Haswell
elif has avx2; then kernel=Sandybridge
elif has avx; then kernel=Nehalem
else kernel=Prescott
fi
# an environment that already forces a kernel (some hosts do, for old OpenBLAS bugs) gets another
if [ "${OPENBLAS_CORETYPE:-}" = "$kernel" ]; then
  if has avx; then kernel=Nehalem; else kernel=Prescott; fi
fi
echo "$kernel"
