"""Desautel's Table 8: normalized Bessel poles for a 1 s settling time.

A module of its own, free of scipy, because the parameter model checks a pole
order against it and the loop process must start without the analysis stack.
"""

from __future__ import annotations

#: Table 8: roots of the normalized Bessel polynomials of order 1..6 for a 1 s settling
#: time (Vaccaro).  Their radii are 0.15-0.40 % larger than an exact 1 % settling
#: scaling; the table's numbers are used as printed (control.md).
BESSEL_POLES: dict[int, tuple[complex, ...]] = {
    1: (-4.6200,),
    2: (-4.0530 + 2.3400j, -4.0530 - 2.3400j),
    3: (-5.0093, -3.9668 + 3.7845j, -3.9668 - 3.7845j),
    4: (-4.0156 + 5.0723j, -4.0156 - 5.0723j, -5.5281 + 1.6553j, -5.5281 - 1.6553j),
    5: (-6.4480, -4.1104 + 6.3142j, -4.1104 - 6.3142j, -5.9268 + 3.0813j, -5.9268 - 3.0813j),
    6: (-4.2169 + 7.5300j, -4.2169 - 7.5300j, -6.2613 + 4.4018j, -6.2613 - 4.4018j,
        -7.1205 + 1.4540j, -7.1205 - 1.4540j),
}
