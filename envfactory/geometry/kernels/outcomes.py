"""motion_proof's outcomes, apart from the kernel so that safety.py reads them without importing numba: the
capsules prove the whole motion; a pair is in doubt at its start or end (below its margin there: coal must measure
it); the ends hold but the compiled pass leaves pairs unproven between them."""

import numpy as np

# numpy integers, not Python ones: numba types a Python global as a literal, and ahead-of-time compiling
# (native.py) does not widen one literal to hold another
PROVEN, DOUBT_AT_ENDS, DOUBT_BETWEEN = np.int64(0), np.int64(1), np.int64(2)
