"""The fuzz suite's session: a folder with the canary and the seeds, and one worker."""

from __future__ import annotations

import fuzz_seeds
import pytest
from fuzz_harness import FuzzEnv


@pytest.fixture(scope="session")
def fuzz_env(shared_data, tmp_path_factory):
    env = FuzzEnv(tmp_path_factory.mktemp("fuzz"), fuzz_seeds.build(shared_data),
                  fuzz_seeds.warmups())
    if env.worker.warm_failures:
        env.close()
        pytest.fail("the fuzz worker's warm-up runs failed: "
                    + "; ".join(env.worker.warm_failures))
    yield env
    env.close()
