"""Adam for the SVI guide's parameters without :mod:`torch.optim`: the same update, bit for bit.

:class:`PlainAdam` is :class:`torch.optim.Adam` with its defaults (no weight decay, no amsgrad,
not maximising) on its single-tensor path, the one it takes for CPU tensors (``foreach`` and
``fused`` off there), written out op for op in the same order, so a seeded fit gives the same
bits (``tests/test_plain_adam.py`` compares them). It exists because every
:class:`torch.optim.Optimizer` imports ``torch._dynamo`` on first use, whatever its options:
``add_param_group``, called by the constructor, is wrapped in ``torch._disable_dynamo``, which
imports it on its first call, and ``step`` in ``_use_grad_for_differentiable``, which imports it
on every call (``foreach``, ``fused``, ``capturable`` and ``differentiable`` change neither;
Pyro's ``ClippedAdam`` is a ``torch.optim.Optimizer`` too). That import cost 1.1 s once a
process, most of a short ``spcopyro fit --method svi`` (docs/speed.md, "An SVI step on
room1dk5"). Used through :class:`pyro.optim.PyroOptim` (:func:`plain_adam`), one instance per
parameter as Pyro's ``Adam`` makes them; ``state_dict`` / ``load_state_dict`` keep Pyro's
``get_state`` / ``set_state`` (and ``save`` / ``load``) working.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable

import torch
from pyro.optim import PyroOptim


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
        self.state: dict[int, dict[str, torch.Tensor | float]] = {}

    @torch.no_grad()
    def step(self, closure: Callable[[], float] | None = None) -> float | None:
        """One update of every parameter with a gradient: torch's ``_single_tensor_adam``."""
        loss = None
        if closure is not None:
            with torch.enable_grad():
                loss = closure()
        beta1, beta2 = self.betas
        for k, param in enumerate(self.params):
            grad = param.grad
            if grad is None:
                continue
            if grad.is_sparse:
                raise RuntimeError("PlainAdam does not support sparse gradients")
            state = self.state.setdefault(k, {})
            if not state:
                state["step"] = 0.0
                state["exp_avg"] = torch.zeros_like(param, memory_format=torch.preserve_format)
                state["exp_avg_sq"] = torch.zeros_like(param, memory_format=torch.preserve_format)
            exp_avg, exp_avg_sq = state["exp_avg"], state["exp_avg_sq"]
            state["step"] = step = state["step"] + 1.0
            exp_avg.lerp_(grad, 1 - beta1)
            exp_avg_sq.mul_(beta2).addcmul_(grad, grad, value=1 - beta2)
            bias_correction1 = 1 - beta1**step
            bias_correction2 = 1 - beta2**step
            step_size = self.lr / bias_correction1
            bias_correction2_sqrt = bias_correction2**0.5
            denom = (exp_avg_sq.sqrt() / bias_correction2_sqrt).add_(self.eps)
            param.addcdiv_(exp_avg, denom, value=-step_size)
        return loss

    def zero_grad(self, set_to_none: bool = True) -> None:
        for param in self.params:
            if param.grad is not None:
                if set_to_none:
                    param.grad = None
                else:
                    param.grad.zero_()

    def state_dict(self) -> dict:
        """The moments and step counts by parameter index, and the hyperparameters."""
        state = {k: {name: v.clone() if isinstance(v, torch.Tensor) else v
                     for name, v in s.items()} for k, s in self.state.items()}  # fmt: skip
        return {"state": state, "lr": self.lr, "betas": self.betas, "eps": self.eps}

    def load_state_dict(self, state_dict: dict) -> None:
        """The state of :meth:`state_dict` (of an optimiser of as many parameters)."""
        self.lr, self.betas, self.eps = state_dict["lr"], state_dict["betas"], state_dict["eps"]
        self.state = {int(k): {name: v.clone() if isinstance(v, torch.Tensor) else v
                               for name, v in s.items()}
                      for k, s in state_dict["state"].items()}  # fmt: skip


def plain_adam(optim_args: dict | Callable[[str], dict]) -> PyroOptim:
    """``pyro.optim.Adam(optim_args)`` with :class:`PlainAdam` in place of torch's (module
    docstring): the same updates; ``optim_args`` a dict or a function of the parameter's name."""
    return PyroOptim(PlainAdam, optim_args)
