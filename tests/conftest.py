import pytest  # noqa: F401
import torch

torch.set_num_threads(1)
