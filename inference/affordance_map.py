"""Affordance-map study (thesis chapter 3): information-gain pushing against exhaustive pushing.

Tables and figures (Figs. 3.5-3.7) go to results/affordance_map/.

    python inference/affordance_map.py [--n-maps N] [--workers K | --scheduler ADDR] [--smoke]
"""

import argparse
import json

from probaff.studies.affordance_map import AffordanceMapConfig, run


def main() -> None:
    """Parse the command line into a study config and run it."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--n-maps", type=int, default=20, help="test maps")
    p.add_argument("--train-maps", type=int, default=20, help="training maps of the classifier")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--out", default="results/affordance_map")
    p.add_argument("--workers", type=int, default=0, help="local Dask workers (0: in process)")
    p.add_argument("--scheduler", default=None, help="address of an existing Dask scheduler")
    p.add_argument("--max-steps", type=int, default=20, help="most pushes per map and policy")
    p.add_argument("--alpha", type=float, default=0.8, help="reward weight of the gain G")
    p.add_argument("--coupling", type=float, default=0.4, help="Ising strength J of the MRF")
    p.add_argument("--along-coupling", type=float, default=None,
                   help="J between neighbours along a direction (default: --coupling)")
    p.add_argument("--symmetry-coupling", type=float, default=None,
                   help="strength of the up/down, left/right symmetry factors (default: none)")
    p.add_argument("--sensor-noise", type=float, default=None,
                   help="range noise of the depth sensor in m (default: the world file's)")
    p.add_argument("--no-stop", action="store_true",
                   help="keep the information-gain loop pushing when every gain is negative")
    p.add_argument("--smoke", action="store_true", help="a tiny run that checks the pipeline")
    a = p.parse_args()
    cfg = AffordanceMapConfig(
        n_maps=2 if a.smoke else a.n_maps, seed=a.seed,
        train_maps=2 if a.smoke else a.train_maps, alpha=a.alpha, coupling=a.coupling,
        symmetry_coupling=a.symmetry_coupling, along_coupling=a.along_coupling,
        max_steps=3 if a.smoke else a.max_steps,
        out=a.out, workers=a.workers, scheduler=a.scheduler, progress=not a.smoke,
        sensor_noise=a.sensor_noise, stop_at_no_gain=not a.no_stop)
    result = run(cfg)
    print(json.dumps({"files": result["files"], "computed": result["computed"]}, indent=1))


if __name__ == "__main__":
    main()
