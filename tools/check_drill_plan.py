"""Check an IREDES drill plan file: it reads with its checksum verified, and writing it back
reproduces it.

    .venv/bin/python tools/check_drill_plan.py PLAN.xml [--holes 83] [--northing-in-x]

Prints the plan (id, holes, depths, types), then writes it with ``write_iredes`` (the
file's own create date) and compares the two files line by line: the lines only the
input has (elements the plan does not keep) and only the output has are listed. Exit
status 0 when the plan reads with its checksum verified, has ``--holes`` holes (when
given), reads back from the written file identical, and the written file's checksum
verifies; 1 otherwise.
"""

from __future__ import annotations

import argparse
import difflib
import re
import sys
from collections import Counter
from pathlib import Path

from planning.drilling.plans import PlanFormatError, read_iredes, write_iredes


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("path", type=Path)
    parser.add_argument("--holes", type=int, default=None, help="expected number of holes")
    parser.add_argument("--northing-in-x", action="store_true")
    args = parser.parse_args(argv)
    raw = args.path.read_bytes()
    ok = True
    try:
        plan = read_iredes(raw, northing_in_x=args.northing_in_x)
    except PlanFormatError as exc:
        print(f"FAIL read: {exc} (at {'/'.join(map(str, exc.loc))})")
        return 1
    depths = plan.depths()
    print(f"read with checksum verified: plan {plan.plan_id!r} ({plan.name!r}), frame "
          f"{plan.frame_name!r}, {len(plan)} holes, depths {depths.min():.0f}-"
          f"{depths.max():.0f} mm, types {dict(Counter(h.type for h in plan.holes))}")
    if args.holes is not None and len(plan) != args.holes:
        print(f"FAIL: {len(plan)} holes, expected {args.holes}")
        ok = False
    created = re.search(rb"<(?:\w+:)?FileCreateDate>([^<]*)<", raw)
    text = write_iredes(plan, northing_in_x=args.northing_in_x,
                        created=created.group(1).decode() if created else None)
    again = read_iredes(text.encode(), northing_in_x=args.northing_in_x)
    same = again == plan
    print(f"round trip (write_iredes, read_iredes with checksum): "
          f"{'identical' if same else 'DIFFERENT'}")
    ok &= same
    source = raw.decode("utf-8").splitlines()
    written = text.splitlines()
    only_in = [line[1:] for line in difflib.unified_diff(source, written, lineterm="", n=0)
               if line.startswith("-") and not line.startswith("---")]
    only_out = [line[1:] for line in difflib.unified_diff(source, written, lineterm="", n=0)
                if line.startswith("+") and not line.startswith("+++")]
    print(f"lines: input {len(source)}, written {len(written)}; "
          f"{len(source) - len(only_in)} of the input's lines written byte for byte")
    for line in only_in:
        print(f"  only in the input:  {line.strip()}")
    for line in only_out:
        print(f"  only in the output: {line.strip()}")
    crlf_in, crlf_out = raw.count(b"\r\n"), text.count("\r\n")
    print(f"line ends: input {'CRLF' if crlf_in else 'LF'}, written CRLF ({crlf_out})")
    print("OK" if ok else "FAIL")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
