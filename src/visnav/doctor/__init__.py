"""``visnav doctor``: find data-chain faults in a live graph or a bag, with evidence and fix.

Architecture: an :class:`Observation` (graph snapshot, per-topic message records and
samples, TF, /clock) is built from a live graph (:func:`observe_live`,
:class:`LiveObserver`) or a bag (:func:`observe_bag`); every check is a plain function
over a :class:`CheckContext` of that observation, so live and bag share all checks;
:func:`diagnose` runs them into a :class:`Report`. The checks are listed in
:data:`CATALOGUE`; ``docs/doctor.md`` documents them and the ``--expect`` schema.

Example::

    from visnav.doctor import doctor_bag
    report = doctor_bag("run/bag")
    print(report.format())
"""

from __future__ import annotations

from visnav.doctor.bag_source import observe_bag
from visnav.doctor.builder import ObservationBuilder, SamplingPolicy
from visnav.doctor.catalogue import CATALOGUE, CATEGORIES, CheckInfo
from visnav.doctor.context import CheckContext
from visnav.doctor.errors import DoctorError, ExpectError
from visnav.doctor.expect import (
    Expectations,
    KnownColor,
    PlannerExpectation,
    TopicExpectation,
    load_expectations,
)
from visnav.doctor.findings import Finding, Report, Severity
from visnav.doctor.live import LiveObserver, observe_live
from visnav.doctor.observation import ClockModel, GraphSnapshot, Observation, TfRecord, TopicData
from visnav.doctor.run import diagnose, doctor_bag, doctor_live

__all__ = [
    "CATALOGUE",
    "CATEGORIES",
    "CheckContext",
    "CheckInfo",
    "ClockModel",
    "DoctorError",
    "Expectations",
    "ExpectError",
    "Finding",
    "GraphSnapshot",
    "KnownColor",
    "LiveObserver",
    "Observation",
    "ObservationBuilder",
    "PlannerExpectation",
    "Report",
    "SamplingPolicy",
    "Severity",
    "TfRecord",
    "TopicData",
    "TopicExpectation",
    "diagnose",
    "doctor_bag",
    "doctor_live",
    "load_expectations",
    "observe_bag",
    "observe_live",
]
