#!/usr/bin/env python3
"""cellphys code generator.

    generate.py --out DIR [--structs DIR] [--forces DIR ...]     write the generated tree
    generate.py --check DIR [...]                                  compare with a checked-in tree

Exit status: 0 ok, 1 drift (with --check), 2 a descriptor error (file: field: reason).
"""
import argparse
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(HERE))

from cellphys_codegen.cxx_printer import UnsupportedExpression  # noqa: E402
from cellphys_codegen.emit import diff_tree, render, write_tree  # noqa: E402
from cellphys_codegen.errors import DescriptorError  # noqa: E402


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    mode = ap.add_mutually_exclusive_group(required=True)
    mode.add_argument("--out", help="directory to write the generated tree into")
    mode.add_argument("--check", help="checked-in tree to compare a fresh generation with")
    ap.add_argument("--structs", default=str(ROOT / "codegen/descriptors/structs"))
    ap.add_argument("--forces", action="append",
                    help="force descriptor directory (repeatable; default: codegen/descriptors/forces)")
    ap.add_argument("--quiet", action="store_true")
    args = ap.parse_args(argv)
    force_dirs = args.forces or [str(ROOT / "codegen/descriptors/forces")]
    t0 = time.perf_counter()
    try:
        files = render(args.structs, force_dirs, ROOT)
    except DescriptorError as e:
        print(f"cellphys codegen: error: {e}", file=sys.stderr)
        return 2
    except UnsupportedExpression as e:
        print(f"cellphys codegen: error: {e}", file=sys.stderr)
        return 2
    if args.check:
        diff = diff_tree(files, args.check)
        if diff:
            sys.stdout.write(diff)
            print(f"\ncellphys codegen: {args.check} differs from a fresh generation (diff above).\n"
                  f"Refresh the checked-in copy with: scripts/regenerate", file=sys.stderr)
            return 1
        if not args.quiet:
            print(f"cellphys codegen: {args.check} is up to date ({len(files)} files)")
        return 0
    write_tree(files, args.out)
    (Path(args.out) / "cellphys/gen/.stamp").write_text("")
    if not args.quiet:
        lines = sum(t.count("\n") for t in files.values())
        print(f"cellphys codegen: {len(files)} files, {lines} lines in {time.perf_counter() - t0:.1f} s -> {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
