"""Build the optional C++ kernel (the regressor and the momentum-observer step): ``python -m sensorless.regressor.native_build [-v]``
(the Makefile runs it after installing; see :mod:`sensorless.regressor.native`). Exit status 1,
with the reason, when it cannot be built: the pure-Python path is then used."""

from __future__ import annotations

import sys

from .native import build


def main(argv: list[str]) -> int:
    try:
        path = build(verbose="-v" in argv)
    except (RuntimeError, FileNotFoundError) as exc:
        print(f"sensorless: native C++ kernel (regressor, observer step, contact projector, friction candidates) not built ({exc}); the pure-Python path is used",
              file=sys.stderr)
        return 1
    print(f"sensorless: native C++ kernel (regressor, observer step, contact projector, friction candidates) built: {path}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
