"""Shared fixtures."""

import numpy as np
import pytest

from hubo_cli.model import load_model


@pytest.fixture(scope="session")
def model():
    return load_model()


@pytest.fixture
def rng():
    return np.random.default_rng(12345)
