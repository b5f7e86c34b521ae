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
# # A cantilever's modes and the critical time step
#
# A concrete plate 2 m × 0.2 m, cut into 80 × 8 rigid elements joined by normal and shear
# penalty springs, and held on its left edge by ground springs. We compute its lowest modes,
# compare them with beam theory, draw them, and find the time step above which explicit
# central difference blows up: `Δt_crit = 2/ω_max`.
#
# Runs as a script (`python cantilever_modes.py`, figures into `out/tutorials/`) or, opened
# with jupytext, as a notebook.

# %%
import math
import os
from pathlib import Path

import matplotlib

if __name__ == "__main__" and "ipykernel" not in os.sys.modules:
    matplotlib.use("Agg")  # a script draws into files
import matplotlib.pyplot as plt
from matplotlib.collections import PolyCollection

import rbsm

HERE = Path(__file__).resolve().parent if "__file__" in globals() else Path.cwd()
SCENE = HERE.parents[1] / "examples" / "scenes" / "cantilever.json"
OUT = Path(os.environ.get("RBSM_TUTORIAL_OUT", "out/tutorials"))
OUT.mkdir(parents=True, exist_ok=True)

scene = rbsm.Scene(SCENE)
model = rbsm.check(scene)
print(f"{model.elements} elements, {model.dofs} free DOFs; Δt_crit = {model.dt_crit:.4e} s")

# %% [markdown]
# ## The lowest modes against beam theory
#
# For a cantilever (Euler–Bernoulli), `f_n = (β_n L)² / (2π L²) · √(EI / ρA)` with
# `β_1 L = 1.8751`, `β_2 L = 4.6941`. The plate is slender (L/h = 10), so the first mode should
# match within a few per cent; higher modes feel shear and the springy support, and sit lower.

# %%
modes = rbsm.eigen(scene, modes=4)
s = scene.to_dict()
mat = next(iter(s["materials"].values()))
(L, h), t = s["bodies"][0]["mesh"]["size"], s["thickness"]
EI, rhoA = mat["E"] * t * h**3 / 12, mat["rho"] * t * h
beam = [(bl**2) / (2 * math.pi * L**2) * math.sqrt(EI / rhoA) for bl in (1.8751, 4.6941)]
for n, (f, fb) in enumerate(zip(modes.frequencies_hz, beam), 1):
    print(f"mode {n}: {f:8.2f} Hz   beam theory {fb:8.2f} Hz   ({f / fb - 1:+.1%})")
assert abs(modes.frequencies_hz[0] / beam[0] - 1) < 0.03, "the first mode is off beam theory"

# %% [markdown]
# ## Drawing the mode shapes
#
# Each element moves rigidly: `u(x) = N_e(x) U_e`. `rbsm.polygons` moves every element's
# vertices so, scaled for the eye. The third mode is the first axial one: the plate stretches
# along its length.

# %%
fig, axes = plt.subplots(3, 1, figsize=(7, 6), sharex=True)
for k, ax in enumerate(axes):
    shape = modes.shapes[k]
    scale = 0.15 / abs(shape[:, :2]).max()
    ax.add_collection(PolyCollection(rbsm.polygons(scene), facecolor="none", edgecolor="0.8", lw=0.3))
    ax.add_collection(
        PolyCollection(rbsm.polygons(scene, shape, scale), facecolor="tab:blue", edgecolor="k", lw=0.2)
    )
    ax.set_title(f"mode {k + 1}: {modes.frequencies_hz[k]:.1f} Hz", fontsize=9)
    ax.set_aspect("equal")
    ax.autoscale_view()
fig.tight_layout()
fig.savefig(OUT / "cantilever_modes.png", dpi=120)

# %% [markdown]
# ## The critical time step
#
# Central difference is stable for `Δt ≤ 2/ω_max`, `ω_max` the highest circular frequency
# (found by Lanczos). `rbsm.stability` checks it by experiment: it bisects the largest step
# that stays bounded, and runs at fractions of `Δt_crit`. Just above it the highest mode grows
# by a constant factor every step, until the run's guard stops it and names the reason.

# %%
print(f"ω_max = {modes.omega_max:.4e} rad/s, Δt_crit = 2/ω_max = {modes.dt_crit:.4e} s")
st = rbsm.stability(scene, fractions=[0.98, 1.02], steps=3000)
print(f"empirical limit: {st.empirical_dt / st.dt_crit:.5f} Δt_crit")
for f in st.fractions:
    print(f"{f['fraction']} Δt_crit: {f['status']}")
assert abs(st.empirical_dt / st.dt_crit - 1) < 1e-3
assert [f["status"] for f in st.fractions] == ["ok", "diverged"]

fig, ax = plt.subplots(figsize=(7, 3.5))
for f in st.fractions:
    h = f["history"]
    ax.plot(h[:, 0] * 1e3, h[:, 2], ".-", label=f"{f['fraction']} Δt_crit: {f['status']}")
ax.set_yscale("log")
ax.set_xlabel("t (ms)")
ax.set_ylabel("kinetic + elastic (J)")
ax.legend()
fig.tight_layout()
fig.savefig(OUT / "cantilever_dt_crit.png", dpi=120)

# %% [markdown]
# A run of the scene with a step above the limit stops by itself, keeping the last state
# that passed its guard, and raises `rbsm.DivergedError`, which carries that run
# (`on_diverge="warn"` would return it with a warning instead):

# %%
try:
    rbsm.run(scene, dt_factor=1.02, steps=3000, exact_dt_crit=True)
    raise AssertionError("the run at 1.02 Δt_crit did not diverge")
except rbsm.DivergedError as e:
    above = e.result
    print(f"diverged at step {e.step}, t = {e.t:.4e} s: {e.reason}")
assert above.status == "diverged"

# %% [markdown]
# The tip deflection under its end load, from the history's probe column:

# %%
r = rbsm.run(scene, steps=20000)
fig, ax = plt.subplots(figsize=(7, 3))
ax.plot(r.history["t"] * 1e3, r.history["tip_v"] * 1e3)
ax.set_xlabel("t (ms)")
ax.set_ylabel("tip v (mm)")
fig.tight_layout()
fig.savefig(OUT / "cantilever_tip.png", dpi=120)
print("figures in", OUT)
