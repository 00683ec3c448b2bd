"""genplan.seq2seq.adjust: the step rules' arithmetic."""

from __future__ import annotations

import torch

from genplan.seq2seq.adjust import _Adam


def test_adam_is_torch_adam_step_for_step() -> None:
    """The written-out Adam (torch.optim imports torch's compiler, seconds) gives torch.optim.Adam's
    iterates exactly, on a non-convex function over 200 steps."""
    torch.manual_seed(0)
    x0 = torch.randn(5, 8)
    a = x0.clone().requires_grad_(True)
    b = x0.clone().requires_grad_(True)
    ref, mine = torch.optim.Adam([a], lr=0.02), _Adam(b, 0.02)
    for _ in range(200):
        (a.grad,) = torch.autograd.grad((a ** 3).sin().sum(), a)
        ref.step()
        (g,) = torch.autograd.grad((b ** 3).sin().sum(), b)
        with torch.no_grad():
            mine.step(b, g)
    assert torch.equal(a, b)
    assert not torch.equal(a, x0)
