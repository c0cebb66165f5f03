"""Blender's command line, as far as the farm job type uses it, run with ``bpy`` as a module:
``python blender_cli.py -b -y --addons MOD FILE.blend --python-exit-code 1 --python-expr EXPR``
does what ``blender`` does with those arguments, in order.  Any other argument is refused
(exit 2), so a command the job type issues that this does not know fails its test rather
than passing unrun.  The user folder is ``$BLENDER_USER_RESOURCES``, as for Blender."""

import sys
import traceback

import bpy

IGNORED = {"-b", "--background", "-y", "--enable-autoexec"}     # bpy as a module: always both


def main(argv):
    exit_code = 0
    args = list(argv)
    while args:
        a = args.pop(0)
        if a in IGNORED:
            continue
        if a == "--addons":
            import addon_utils
            for module in args.pop(0).split(","):
                if addon_utils.enable(module, default_set=True, persistent=True) is None:
                    print(f"blender_cli: cannot enable add-on {module}", file=sys.stderr)
                    return 1
        elif a == "--python-exit-code":
            exit_code = int(args.pop(0))
        elif a == "--python-expr":
            expr = args.pop(0)
            try:
                exec(compile(expr, "<string>", "exec"), {"__name__": "__main__"})
            except Exception:  # Blender prints the traceback and goes on (or exits with the code)
                traceback.print_exc()
                if exit_code:
                    return exit_code
        elif a.endswith(".blend") and not a.startswith("-"):
            bpy.ops.wm.open_mainfile(filepath=a)
        else:
            print(f"blender_cli: argument not supported here: {a}", file=sys.stderr)
            return 2
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
