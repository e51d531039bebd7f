"""`nurbsinterp warmup`: compile every kernel now, so that no later command waits for it."""
from __future__ import annotations

import click

from .common import echo_result, json_text


@click.command()
@click.option("--force", is_flag=True, help="Run the warm-up even if this version's kernels are compiled already.")
@click.option("--json", "as_json", is_flag=True, help="Print the result as one JSON object on stdout.")
def warmup(force, as_json):
    """Compile the numeric kernels of every command, once (about 6 minutes on 2 cores).

    Any command does this on its first run by itself, saying so; run it ahead
    of time after installing (in a Dockerfile, a CI step, before a benchmark).
    Later runs, and `warmup` itself, load the compiled kernels from the cache.

    \b
    nurbsinterp warmup
    """
    import time

    from .._cache import cache_dir, kernels_warm, mark_warm
    from ..warmup import warm_up
    from .report import warmup_progress

    was_warm = kernels_warm() and not force
    t0 = time.perf_counter()
    if was_warm:
        result = warm_up()
    else:
        with warmup_progress("nurbsinterp: compiling the numeric kernels of every command "
                             "(about 6 minutes on 2 cores)") as progress:
            result = warm_up(progress)
        mark_warm()
    result = {"seconds": time.perf_counter() - t0, "kernels_compiled": result["compiled"],
              "already_warm": was_warm, "cache": str(cache_dir())}
    if as_json:
        echo_result(json_text(result))
    else:
        echo_result(f"kernels ready in {result['cache']} ({result['kernels_compiled']} compiled, "
                    f"{result['seconds']:.1f} s)")
