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


def pytest_collection_modifyitems(config, items):
    """Long simulation tests (``@pytest.mark.slow``) first: pytest-xdist hands the tests out in
    this order, one or two at a time, so the longest start at once and the short ones fill the
    workers' gaps at the end instead of one long test running alone."""
    items.sort(key=lambda item: item.get_closest_marker("slow") is None)
