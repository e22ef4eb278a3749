"""`python -m tools.bench [flags]` (from the repository root; `make bench`): see tools.bench.cli."""

from tools.bench.cli import bench

if __name__ == "__main__":
    bench(prog_name="python -m tools.bench")
