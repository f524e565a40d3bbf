"""``python -m cosim.models.native``: build the compiled kernels (``make setup`` / ``make fmus``).

Without a C compiler (or when the build fails) it says so and exits 0: the models then
run their numpy code, with the same numbers, only slower.
"""

import sys

from . import build, build_log, status

if __name__ == "__main__":
    try:
        print(f"built {build()}; models use: {status()}")
    except RuntimeError as exc:
        log = build_log().strip()
        print(f"{log}\nmodels/native: {exc}\nmodels use: {status()}".strip(), file=sys.stderr)
