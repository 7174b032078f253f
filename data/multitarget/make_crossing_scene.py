"""Write crossing_scene.csv: the simulated scene of issue 23 as a file of unlabelled detections.

    python data/multitarget/make_crossing_scene.py

20 targets crossing and turning (0.5–4 °/s), P_D = 0.9, 10 clutter detections per scan, σ = 10 m, 200 scans of
1 s (:func:`hybridtrack.engine.scenes.crossing_scene`, seed 11).  Columns ``scan,time,x,y`` (metres), no identity;
``crossing_scene_truth.csv`` holds the true positions (``time,target,x,y``) for scoring.
"""

from pathlib import Path

import numpy as np

from hybridtrack.engine.scenes import crossing_scene

HERE = Path(__file__).resolve().parent


def main() -> None:
    scene = crossing_scene(seed=11)
    rows = np.column_stack([scene.scan, scene.times, scene.z])
    np.savetxt(HERE / "crossing_scene.csv", rows, fmt=["%d", "%.1f", "%.2f", "%.2f"], delimiter=",", header="scan,time,x,y", comments="")
    truth = scene.truth
    table = np.column_stack([truth.times, truth.ids, truth.positions])
    np.savetxt(
        HERE / "crossing_scene_truth.csv", table, fmt=["%.1f", "%d", "%.2f", "%.2f"], delimiter=",", header="time,target,x,y", comments=""
    )


if __name__ == "__main__":
    main()
