"""A Ray address that does not answer is refused within seconds, naming it (Ray itself retries
for minutes); a malformed one is refused before any connection."""
import time

import pytest

from workbench.compute.ray_cluster import check_address
from workbench.errors import ParameterError


@pytest.mark.parametrize("address", ["127.0.0.1:1", "ray://127.0.0.1:1"])
def test_an_address_with_nothing_behind_it_fails_fast_naming_it(address):
    t0 = time.perf_counter()
    with pytest.raises(ParameterError, match="--address.*127.0.0.1:1"):
        check_address(address)
    assert time.perf_counter() - t0 < 30


@pytest.mark.parametrize("address", ["bogus", "host:", ":1234", "ray://nohostport"])
def test_a_malformed_address_is_refused(address):
    with pytest.raises(ParameterError, match="HOST:PORT"):
        check_address(address)
