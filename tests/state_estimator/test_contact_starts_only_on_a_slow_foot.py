"""Spring contact: a swing fast enough to load the springs by its own inertia is no contact;
a slow foot under the same load is, and a foot in contact stays so whatever its speed."""

from __future__ import annotations

import numpy as np

from processes.state_estimator.contact import ContactParams, SpringContact
from processes.state_estimator.params import EstimatorParams
from runtime.params import read

P = ContactParams()
LOADED = -np.full((2, 2), 0.03)  # both legs' springs deflected: ~134 N each, over on_n


def test_a_loaded_spring_on_a_fast_foot_starts_no_contact():
    c = SpringContact(P)
    c.update(LOADED, np.array((2.5, 2.5)))
    assert float(c.force[0]) > P.on_n
    assert c.in_contact == [False, False]


def test_the_same_load_on_a_slow_foot_starts_a_contact():
    c = SpringContact(P)
    c.update(LOADED, np.array((0.3, 2.5)))
    assert c.in_contact == [True, False]


def test_a_foot_in_contact_stays_in_contact_while_loaded_whatever_its_speed():
    c = SpringContact(P)
    c.update(LOADED, np.array((0.3, 0.3)))
    c.update(LOADED, np.array((3.0, 3.0)))
    assert c.in_contact == [True, True]
    c.update(np.zeros((2, 2)), np.array((0.0, 0.0)))  # unloaded: off
    assert c.in_contact == [False, False]


def test_the_speed_threshold_comes_from_the_gains_file():
    p = read(EstimatorParams, {"contact": {"touchdown_speed_mps": 0.5}}, "se.yaml")
    assert p.contact.touchdown_speed_mps == 0.5
