"""Eight full-scale vessels under the default fjord weather, stepped together.

Run: python examples/quickstart.py
"""

from __future__ import annotations

import numpy as np

from asvtwin.environment import Environment, default_environment
from asvtwin.vessel import BatchSimulator, cybership2_full_scale


def main() -> np.ndarray:
    p = cybership2_full_scale()
    env = Environment(default_environment(p))
    rng = np.random.default_rng(0)
    state = env.initial_state(rng)
    x0 = np.zeros((8, 6))
    x0[:, 2] = np.linspace(0, 2 * np.pi, 8, endpoint=False)  # eight headings
    sim = BatchSimulator(p, x0, dt_s=0.5)
    for _ in range(240):  # two minutes at half the largest surge thrust
        x = sim.step([0.5 * p.actuators.tau_max[0], 0.0, 0.0],
                     d=env.forces(p, sim.state, state))
        state = env.advance(state, 0.5, rng)
    for i, xi in enumerate(x):
        print(f"vessel {i}: north {xi[0]:8.1f} m  east {xi[1]:8.1f} m  "
              f"speed {np.hypot(xi[3], xi[4]):.2f} m/s")
    return x


if __name__ == "__main__":
    main()
