"""The trained policy as plain arrays: export from stable-baselines3, evaluate in numpy.

A policy file is an ``.npz`` of float64 arrays ``W0, b0, W1, b1, ...`` (the policy MLP,
tanh after each hidden layer), ``W_out, b_out`` (the action mean) and ``meta`` (a JSON
string as a 0-d unicode array: format, observation size, rays, the model-scale reference
length and step, the setup it was trained in). Loading never unpickles
(``np.load(..., allow_pickle=False)``); the action is the Gaussian policy's mean, clipped
to [−1, 1] (deterministic evaluation).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from asvtwin.errors import ConfigError

__all__ = ["FORMAT", "NumpyPolicy", "export_sb3_policy"]

#: Format tag written into every policy file's metadata.
FORMAT = "asvtwin.rl.policy/1"


class PolicyFileError(ConfigError):
    """A policy file is missing, foreign or has arrays of the wrong shape."""


class NumpyPolicy:
    """A feed-forward policy evaluated with numpy.

    Parameters
    ----------
    weights : list of (W, b)
        Hidden layers (tanh) then the output layer; ``W`` has shape (out, in).
    meta : dict
        At least ``obs_dim``; see :func:`export_sb3_policy`.
    """

    def __init__(self, weights: list[tuple[NDArray[np.float64], NDArray[np.float64]]],
                 meta: dict[str, Any]) -> None:
        self.layers = weights
        self.meta = meta
        self.obs_dim = int(meta["obs_dim"])

    @classmethod
    def load(cls, path: str | Path) -> NumpyPolicy:
        """Read and check a policy file; :class:`PolicyFileError` names what is wrong."""
        path = Path(path)
        try:
            with np.load(path, allow_pickle=False) as z:
                arrays = {k: z[k] for k in z.files}
        except FileNotFoundError:
            raise
        except (ValueError, OSError, EOFError) as exc:
            raise PolicyFileError(f"{path}: not a readable .npz policy file ({exc})") from exc
        if "meta" not in arrays:
            raise PolicyFileError(f"{path}: no 'meta' array; expected a policy written by "
                                  f"export_sb3_policy (format {FORMAT})")
        try:
            meta = json.loads(str(arrays["meta"]))
        except json.JSONDecodeError as exc:
            raise PolicyFileError(f"{path}: 'meta' is not JSON: {exc}") from exc
        if meta.get("format") != FORMAT:
            raise PolicyFileError(f"{path}: format {meta.get('format')!r}, expected {FORMAT!r}")
        layers = []
        k = 0
        while f"W{k}" in arrays:
            layers.append((arrays[f"W{k}"], arrays.get(f"b{k}")))
            k += 1
        if "W_out" not in arrays or not layers:
            raise PolicyFileError(f"{path}: expected arrays W0, b0, ..., W_out, b_out; "
                                  f"found {sorted(arrays)}")
        layers.append((arrays["W_out"], arrays.get("b_out")))
        n_in = int(meta.get("obs_dim", -1))
        for j, (W, b) in enumerate(layers):
            name = f"W{j}" if j < len(layers) - 1 else "W_out"
            if W.ndim != 2 or W.shape[1] != n_in or b is None or b.shape != (W.shape[0],):
                raise PolicyFileError(
                    f"{path}: {name} has shape {W.shape} (bias "
                    f"{None if b is None else b.shape}), expected (k, {n_in}) with a bias (k,)")
            if not (np.isfinite(W).all() and np.isfinite(b).all()):
                raise PolicyFileError(f"{path}: {name} holds NaN or inf")
            n_in = W.shape[0]
        if n_in != 2:
            raise PolicyFileError(f"{path}: the output layer has {n_in} outputs, expected 2 "
                                  f"(surge, yaw)")
        return cls([(W.astype(np.float64), np.asarray(b, dtype=np.float64))
                    for W, b in layers], meta)

    def act(self, obs: ArrayLike) -> NDArray[np.float64]:
        """Deterministic actions (n, 2) in [−1, 1] for observations (n, obs_dim) or (obs_dim,)."""
        h = np.asarray(obs, dtype=np.float64)
        one = h.ndim == 1
        h = np.atleast_2d(h)
        if h.shape[1] != self.obs_dim:
            from asvtwin.errors import StateError

            raise StateError(f"observation must have {self.obs_dim} entries, actually: "
                             f"{h.shape[1]}")
        for W, b in self.layers[:-1]:
            h = np.tanh(h @ W.T + b)
        W, b = self.layers[-1]
        a = np.clip(h @ W.T + b, -1.0, 1.0)
        return a[0] if one else a


def export_sb3_policy(model: Any, path: str | Path, meta: dict[str, Any]) -> Path:
    """Write an SB3 PPO ``MlpPolicy``'s actor (tanh MLP + action mean) as ``.npz``."""
    import torch

    pol = model.policy
    linears = [m for m in pol.mlp_extractor.policy_net if isinstance(m, torch.nn.Linear)]
    acts = [m for m in pol.mlp_extractor.policy_net if not isinstance(m, torch.nn.Linear)]
    if any(not isinstance(m, torch.nn.Tanh) for m in acts):
        raise ConfigError("export_sb3_policy supports tanh MLP policies only")
    arrays: dict[str, Any] = {}
    for k, lin in enumerate(linears):
        arrays[f"W{k}"] = lin.weight.detach().cpu().numpy().astype(np.float64)
        arrays[f"b{k}"] = lin.bias.detach().cpu().numpy().astype(np.float64)
    arrays["W_out"] = pol.action_net.weight.detach().cpu().numpy().astype(np.float64)
    arrays["b_out"] = pol.action_net.bias.detach().cpu().numpy().astype(np.float64)
    m = dict(meta, format=FORMAT)
    arrays["meta"] = np.array(json.dumps(m))
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    np.savez(path, **arrays)
    return path
