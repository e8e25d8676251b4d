"""The scan's ground level (jaxppo.model._overlap.quiet_model): the light
curve of a tilt at which the tilted planet touches no disk."""

import numpy as np

import jaxppo as jp
from jaxppo.model._overlap import quiet_model


def _pair(star):
    b = jp.Planet(period=3.0, t0=0.0, a=10.0, inc=90.0, radius=0.1, name="b")
    c = jp.Planet(period=10.0, t0=0.0, a=20.0, inc=90.0, radius=0.1, name="c")
    return jp.System(star, [b, c])


def test_quiet_model_is_each_disk_alone_for_two_planets_on_any_star():
    """With two planets the ground level is each disk's own dip (sweep's
    no_overlap), also on a star with rotating spots, whose frames need
    their times and whose own flux F_0(t) is below 1 (quiet_model raised
    "a star with rotating spots needs the time of each frame")."""
    t = np.arange(-0.1, 0.1, 4 / 1440)
    star = jp.Star.quadratic(0.4, 0.25)
    spotted = star.with_spots(lat=[10.0], lon=[0.0], radius=[8.0], contrast=[0.5], period=5.0, inc=90.0)
    wants = []
    for s in (star, spotted):
        system = _pair(s)
        want = np.asarray(jp.sweep(system, t, [0.0], cases="same", no_overlap=True))[0, 0]
        got = quiet_model(system, t, "same")
        assert np.max(np.abs(got - want)) < 1e-9, (s, np.max(np.abs(got - want)))
        wants.append(want)
    assert np.max(np.abs(wants[1] - wants[0])) > 1e-3  # the spots dim the star: F_0(t) enters
