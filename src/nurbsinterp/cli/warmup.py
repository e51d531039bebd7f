"""`nurbsinterp warmup`: compile every kernel now, so that no later command waits for it."""
from __future__ import annotations

import click

from .common import compile_everything, echo_result, json_text


@click.command()
@click.option("--force", is_flag=True, help="Run the warm-up even if this version's kernels are compiled already.")
@click.option("--json", "as_json", is_flag=True, help="Print the result as one JSON object on stdout.")
def warmup(force, as_json):
    """Compile the numeric kernels of every command, once (about 2 minutes on 2 cores).

    Each command compiles the kernels it calls on its first run by itself, saying
    so; this compiles every command's ahead of time, on every core (after
    installing: in a Dockerfile, a CI step, before a benchmark or a sweep), so that
    no later command compiles.  Later runs, and `warmup` itself, load the compiled
    kernels from the cache.

    \b
    nurbsinterp warmup
    """
    import time

    from .._cache import cache_dir

    t0 = time.perf_counter()
    result = compile_everything(force, check=True)
    result = {"seconds": time.perf_counter() - t0, "kernels_compiled": result["compiled"],
              "already_warm": result["already_warm"], "cache": str(cache_dir())}
    if as_json:
        echo_result(json_text(result))
    else:
        echo_result(f"kernels ready in {result['cache']} ({result['kernels_compiled']} compiled, "
                    f"{result['seconds']:.1f} s)")
