"""Adam for the SVI guide's parameters without a :class:`torch.optim.Optimizer`: the same update.

:class:`PlainAdam` holds the per-parameter state of :class:`torch.optim.Adam` with its defaults
(no weight decay, no amsgrad, not maximising) and updates it with torch's own functional
``torch.optim.adam.adam`` on its single-tensor path (``foreach=False``, the path
:class:`torch.optim.Adam` takes for CPU tensors), so a seeded fit gives the same bits
(``tests/test_plain_adam.py`` compares them). It exists because every
:class:`torch.optim.Optimizer` imports ``torch._dynamo`` on first use, whatever its options:
``add_param_group``, called by the constructor, is wrapped in ``torch._disable_dynamo``, which
imports it on its first call, and ``step`` in ``_use_grad_for_differentiable``, which imports it
on every call (``foreach``, ``fused``, ``capturable`` and ``differentiable`` change neither;
Pyro's ``ClippedAdam`` is a ``torch.optim.Optimizer`` too). The functional ``adam`` imports it
only under compilation (checked in a fresh process, torch 2.14.1). That import cost 1.1 s once a
process, most of a short ``spcopyro fit --method svi`` (docs/speed.md, "An SVI step on
room1dk5"). Used through :class:`pyro.optim.PyroOptim` (:func:`plain_adam`), one instance per
parameter as Pyro's ``Adam`` makes them; ``state_dict`` / ``load_state_dict`` keep Pyro's
``get_state`` / ``set_state`` (and ``save`` / ``load``) working.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable

import torch
from pyro.optim import PyroOptim
from torch.optim.adam import adam as _functional_adam


class PlainAdam:
    """``torch.optim.Adam(params, lr, betas, eps)`` on CPU, without torch.optim (module
    docstring): per parameter the moments ``exp_avg``, ``exp_avg_sq`` (its shape) and the step
    count."""

    def __init__(
        self,
        params: Iterable[torch.Tensor],
        lr: float = 1e-3,
        betas: tuple[float, float] = (0.9, 0.999),
        eps: float = 1e-8,
    ) -> None:
        if not lr >= 0 or not eps >= 0 or not all(0 <= b < 1 for b in betas):
            raise ValueError(f"PlainAdam needs lr >= 0, eps >= 0, betas in [0, 1): got "
                             f"lr={lr}, betas={betas}, eps={eps}")  # fmt: skip
        self.params = list(params)
        self.lr, self.betas, self.eps = float(lr), (float(betas[0]), float(betas[1])), float(eps)
        self.state: dict[int, dict[str, torch.Tensor]] = {}

    @torch.no_grad()
    def step(self, closure: Callable[[], float] | None = None) -> float | None:
        """One update of every parameter with a gradient: torch's functional ``adam``."""
        loss = None
        if closure is not None:
            with torch.enable_grad():
                loss = closure()
        params, grads, exp_avgs, exp_avg_sqs, steps = [], [], [], [], []
        for k, param in enumerate(self.params):
            if param.grad is None:
                continue
            if param.grad.is_sparse:
                raise RuntimeError("PlainAdam does not support sparse gradients")
            state = self.state.setdefault(k, {})
            if not state:  # as torch.optim.Adam: the step a 0-d tensor of its scalar dtype
                state["step"] = torch.tensor(0.0, dtype=_step_dtype())
                state["exp_avg"] = torch.zeros_like(param, memory_format=torch.preserve_format)
                state["exp_avg_sq"] = torch.zeros_like(param, memory_format=torch.preserve_format)
            params.append(param)
            grads.append(param.grad)
            exp_avgs.append(state["exp_avg"])
            exp_avg_sqs.append(state["exp_avg_sq"])
            steps.append(state["step"])  # [], incremented in place by adam
        if params:
            beta1, beta2 = self.betas
            # only the arguments torch >= 2.1 (pyproject's pin) has
            _functional_adam(params, grads, exp_avgs, exp_avg_sqs, [], steps, foreach=False,
                             amsgrad=False, beta1=beta1, beta2=beta2, lr=self.lr,
                             weight_decay=0.0, eps=self.eps, maximize=False)  # fmt: skip
        return loss

    def zero_grad(self, set_to_none: bool = True) -> None:
        for param in self.params:
            if param.grad is not None:
                if set_to_none:
                    param.grad = None
                else:
                    param.grad.zero_()

    def state_dict(self) -> dict:
        """The moments and step counts (0-d tensors) by parameter index, and the
        hyperparameters."""
        state = {k: {name: v.clone() for name, v in s.items()} for k, s in self.state.items()}
        return {"state": state, "lr": self.lr, "betas": self.betas, "eps": self.eps}

    def load_state_dict(self, state_dict: dict) -> None:
        """The state of :meth:`state_dict` (of an optimiser of as many parameters); a step saved
        as a number (before the step was a tensor) is made the 0-d tensor ``adam`` needs."""
        self.lr, self.betas, self.eps = state_dict["lr"], state_dict["betas"], state_dict["eps"]
        self.state = {
            int(k): {name: _loaded(v) for name, v in s.items()}
            for k, s in state_dict["state"].items()
        }


def _step_dtype() -> torch.dtype:
    """The dtype of torch.optim.Adam's step tensor (``torch.optim.optimizer._get_scalar_dtype``)."""
    return torch.float64 if torch.get_default_dtype() == torch.float64 else torch.float32


def _loaded(value: torch.Tensor | float) -> torch.Tensor:
    """A copy of one saved state entry; a number (only ever a step) becomes a 0-d tensor."""
    if isinstance(value, torch.Tensor):
        return value.clone()
    return torch.tensor(float(value), dtype=_step_dtype())


def plain_adam(optim_args: dict | Callable[[str], dict]) -> PyroOptim:
    """``pyro.optim.Adam(optim_args)`` with :class:`PlainAdam` in place of torch's (module
    docstring): the same updates; ``optim_args`` a dict or a function of the parameter's name."""
    return PyroOptim(PlainAdam, optim_args)
