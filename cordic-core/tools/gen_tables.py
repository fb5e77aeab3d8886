#!/usr/bin/env python3
"""Prints the CORDIC constants used by cordic-core/src/tables.rs.

Angles are in "wide binary angle" units: 2^64 = one full turn, so that the
library's angle arithmetic is plain wrapping integer arithmetic. The gain is
the product of 1/sqrt(1 + 2^-2i) over the iterations, as a 0.64 fixed-point
fraction. Run with the iteration count as the only argument.
"""
import sys
from decimal import Decimal, getcontext

getcontext().prec = 80


def atan(x):
    # Taylor series; x <= 1 converges slowly at 1, so use atan(1) = pi/4 there.
    total, term, n, x2 = Decimal(0), x, 0, x * x
    while abs(term) > Decimal(10) ** -70:
        total += term / (2 * n + 1) if n % 2 == 0 else -term / (2 * n + 1)
        term *= x2
        n += 1
    return total


def pi():
    # Machin: pi/4 = 4 atan(1/5) - atan(1/239)
    return 4 * (4 * atan(Decimal(1) / 5) - atan(Decimal(1) / 239))


def main():
    n = int(sys.argv[1]) if len(sys.argv) > 1 else 40
    turn = Decimal(2) ** 64
    two_pi = 2 * pi()
    print(f"/// atan(2^-i) in wide binary angle units (2^64 = 360°), i = 0..{n}.")
    print(f"pub(crate) const ATAN_WIDE: [i64; {n}] = [")
    for i in range(n):
        a = (pi() / 4) if i == 0 else atan(Decimal(2) ** -i)
        print(f"    {int((a / two_pi * turn).to_integral_value()):#x},")
    print("];")
    k = Decimal(1)
    for i in range(n):
        k /= (1 + Decimal(2) ** (-2 * i)).sqrt()
    print(f"/// The inverse CORDIC gain after {n} iterations, 0.64 fixed point.")
    print(f"pub(crate) const INV_GAIN_Q64: u64 = {int((k * turn).to_integral_value()):#x};")
    print("/// 2*pi as 4.60 fixed point: converts a wide binary angle to radians.")
    print(f"pub(crate) const TWO_PI_Q60: u64 = {int((two_pi * Decimal(2) ** 60).to_integral_value()):#x};")
    print("/// 2^(2^-(j+1)) as 2.62 fixed point, j = 0..27: the factors of QEXP's fraction bits.")
    print("pub(crate) const EXP2_BIT_Q62: [u64; 27] = [")
    ln2 = Decimal(2).ln()
    for j in range(27):
        v = (ln2 * Decimal(2) ** -(j + 1)).exp()
        print(f"    {int((v * Decimal(2) ** 62).to_integral_value()):#x},")
    print("];")


main()
