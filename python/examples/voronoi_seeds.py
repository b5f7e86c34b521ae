# ---
# jupyter:
#   jupytext:
#     formats: py:percent
#   kernelspec:
#     display_name: Python 3
#     language: python
#     name: python3
# ---

# %% [markdown]
# # How much does a Voronoi mesh matter? A seed study on Dask
#
# A rock panel 1 m × 0.5 m on ground springs, cut into 400 Voronoi cells, takes a short shear
# pulse on its top edge. The cells come from random sites: another seed gives another mesh of
# the same density. Over a set of seeds we measure how far the top's displacement history moves
# (against the run of the smallest time step, as `rbsm tradeoff` does), how `Δt_crit` changes
# with the mesh, and what each run costs.
#
# Every seed is an independent run: `rbsm.sweep` sends them to a Dask cluster. Here it is a
# `LocalCluster` of two worker processes; the same call runs on any cluster a
# `distributed.Client` reaches (SSH, Slurm through dask-jobqueue, Kubernetes), each task
# carrying the whole scene, so the workers need only `pip install rbsm`.
#
# Runs as a script (figures into `out/tutorials/`) or, opened with jupytext, as a notebook.

# %%
import os
from pathlib import Path

import matplotlib

if __name__ == "__main__" and "ipykernel" not in os.sys.modules:
    matplotlib.use("Agg")
import matplotlib.pyplot as plt
from matplotlib.collections import PolyCollection

import rbsm

HERE = Path(__file__).resolve().parent if "__file__" in globals() else Path.cwd()
OUT = Path(os.environ.get("RBSM_TUTORIAL_OUT", "out/tutorials"))
SEEDS = range(int(os.environ.get("RBSM_TUTORIAL_SEEDS", "8")))

# %% [markdown]
# ## The scene
#
# The bundled panel, with a probe on the top edge's horizontal displacement and no VTK frames
# (a study writes no files).

# %%
panel = rbsm.Scene(HERE.parents[1] / "examples" / "scenes" / "voronoi_panel.json").to_dict()
panel["output"] = {"every": 10, "probes": [{"name": "top_u", "at": [0.5, 0.49], "dof": "u"}]}
scene = rbsm.Scene(panel)
print(rbsm.check(scene).elements, "elements")


def draw(ax, seed):
    """The panel's mesh for `seed`."""
    s = dict(panel)
    s["bodies"] = [dict(panel["bodies"][0], mesh=dict(panel["bodies"][0]["mesh"], seed=seed))]
    ax.add_collection(PolyCollection(rbsm.polygons(s), facecolor="0.9", edgecolor="k", lw=0.3))
    ax.set_title(f"seed {seed}", fontsize=9)
    ax.set_aspect("equal")
    ax.autoscale_view()
    ax.axis("off")


# %% [markdown]
# ## The study, on a Dask cluster
#
# Scripts that start worker processes need the `if __name__ == "__main__":` guard (a
# notebook runs as `__main__`). `store=` keeps each finished seed, so an interrupted study
# goes on where it stopped.


# %%
def study():
    from distributed import Client, LocalCluster

    with LocalCluster(n_workers=2, threads_per_worker=1, dashboard_address=None) as cluster:
        with Client(cluster) as client:
            return rbsm.sweep(
                scene,
                {"seed": list(SEEDS)},
                executor=client,
                progress=lambda r: print("done:", dict(r["settings"])),
            )


if __name__ == "__main__":
    OUT.mkdir(parents=True, exist_ok=True)
    table = study()
    print(table.attrs["reference"])
    print(table[["seed", "elements", "dt_crit", "steps", "wall_s", "status", "error"]].to_string())
    assert (table.status == "ok").all()
    others = table.error.dropna()
    print(
        f"over {len(table)} seeds: Δt_crit {table.dt_crit.min():.3e} – {table.dt_crit.max():.3e} s, "
        f"top_u differs from the reference seed by {others.min():.1%} – {others.max():.1%} RMS"
    )

    # %% [markdown]
    # ## What the seed changes

    # %%
    fig, axes = plt.subplots(1, 3, figsize=(11, 3.2))
    draw(axes[0], SEEDS[0])
    axes[1].bar(table.seed, table.dt_crit * 1e6)
    axes[1].set_xlabel("seed")
    axes[1].set_ylabel("Δt_crit (µs)")
    axes[2].scatter(table.wall_s, table.error)
    for _, row in table.iterrows():
        axes[2].annotate(str(row.seed), (row.wall_s, row.error), fontsize=7)
    axes[2].set_xlabel("wall time per run (s)")
    axes[2].set_ylabel("RMS difference of top_u")
    fig.tight_layout()
    fig.savefig(OUT / "voronoi_seeds.png", dpi=120)
    print("figure in", OUT)
