"""Upper body: chest open; lower body: front jumping jack (Table 1 row 1; ω 0.2/0.8 as the
authors' config)."""

from _common import GYM, composite


def config():
    return composite((GYM + "chest_open+walk_in_place.json",), (GYM + "front_jumping_jack.json",), weights=(0.2, 0.8))
