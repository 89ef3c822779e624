import pytest

from slopelander.model import Model


@pytest.fixture(scope="session")
def model() -> Model:
    return Model.default()
