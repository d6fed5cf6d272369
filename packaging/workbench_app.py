"""Entry point of the frozen application (PyInstaller one-folder bundle).

    camera-workbench                  open the window (where there is a display)
    camera-workbench PROJECT          open a project in the window
    camera-workbench --self-test      headless: a small pipeline and a 32×24 city render, exit 0 if they work
    camera-workbench cli ARGS…        the `workbench` command line, e.g. `cli simulate paper_camera --out out`
"""
import os
import sys


def _bundle_dir() -> str:
    return getattr(sys, "_MEIPASS", os.path.dirname(os.path.abspath(__file__)))


def main() -> int:
    # The bundled LLVM 19 for Mitsuba's fast variants, unless the user points elsewhere.
    bundled_llvm = os.path.join(_bundle_dir(), "llvm", "libLLVM.so.19.1")
    if os.path.isfile(bundled_llvm):
        os.environ.setdefault("DRJIT_LIBLLVM_PATH", bundled_llvm)
    from workbench.cli import main as cli_main

    args = sys.argv[1:]
    if args[:1] == ["--self-test"]:
        return cli_main(["self-test", *args[1:]])
    if args[:1] == ["cli"]:
        return cli_main(args[1:])
    if args[:1] in (["--version"], ["-h"], ["--help"]):
        return cli_main(args)
    return cli_main(["gui", *args])


if __name__ == "__main__":
    # the window's worker processes (render worker, side process) are spawned: in the bundle a
    # spawned child runs this executable, which must become that child, not a second window
    import multiprocessing
    multiprocessing.freeze_support()
    sys.exit(main())
