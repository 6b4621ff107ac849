"""``python -m benchmarks.scenes --seed N --out DIR [--size small] [--held-out]``: write one scene of the family."""
from __future__ import annotations

import argparse

from .generate import generate
from .spec import SIZES
from .splits import HeldOutError, check_seeds


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--seed", type=int, required=True)
    parser.add_argument("--out", required=True)
    parser.add_argument("--size", choices=sorted(SIZES), default="small")
    parser.add_argument("--held-out", action="store_true", help="allow a held-out seed (only to fill the table)")
    args = parser.parse_args()
    try:
        check_seeds([args.seed], args.held_out)
    except HeldOutError as err:
        raise SystemExit(f"error: {err}") from None
    print(generate(args.seed, args.out, args.size))


if __name__ == "__main__":
    main()
