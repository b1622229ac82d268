"""What a head class means to a search: a person to find, a life-saving appliance, or an object.

A head may name classes that are not search targets (boats, jetskis, buoys): telling them apart
is how a boat stops being called a swimmer. Everything downstream asks this module which
classes are people: evaluation scores only those, the mission confirms and alerts only those
and the appliances (a life ring without a person is worth its own alert, never a swimmer
alert), and the objects are tracked but never alerted.

Names are compared normalised (lower case, runs of other characters than letters and digits as
``_``). A class this module does not know is taken for a person: a head trained on other
names keeps alerting, since a missed person costs more than a false alert.
"""

from __future__ import annotations

import functools
import re
from collections.abc import Sequence
from typing import Literal

import numpy as np

Role = Literal["person", "appliance", "object"]

#: Classes that are people to find (any name not listed below is taken for one too).
PERSON_CLASSES: frozenset[str] = frozenset({"swimmer", "swimmer_with_life_jacket", "person"})
#: Normalised dataset category names that mean a head class although they are spelled otherwise
#: (SeaDronesSee MOT calls a swimmer with a life jacket a ``floater``).
CATEGORY_ALIASES: dict[str, str] = {
    "floater": "swimmer_with_life_jacket",
    "swimmer_with_lifejacket": "swimmer_with_life_jacket",
}
#: Life-saving appliances (life rings, life rafts): worth their own alert.
APPLIANCE_CLASSES: frozenset[str] = frozenset(
    {"life_saving_appliances", "life_saving_appliance", "life_ring", "lifebuoy", "life_raft"}
)
#: Things a search meets that are neither (never alerted), VisDrone's vehicles among them.
OBJECT_CLASSES: frozenset[str] = frozenset(
    {"boat", "jetski", "buoy", "bird", "debris", "sun_glint", "car", "vehicle", "animal"}
    | {"bicycle", "van", "truck", "tricycle", "awning_tricycle", "bus", "motor", "others"}
)

#: The maritime head's classes: the people first (class ids 0 and 1 as in every earlier head),
#: then what SeaDronesSee annotates beside them.
MARITIME_CLASSES: tuple[str, ...] = (
    "swimmer",
    "swimmer_with_life_jacket",
    "boat",
    "jetski",
    "buoy",
    "life_saving_appliances",
)


def normalise_class(name: str) -> str:
    """``"Life-saving appliances"`` -> ``"life_saving_appliances"``."""
    return re.sub(r"[^a-z0-9]+", "_", name.lower()).strip("_")


@functools.cache
def role_of(name: str) -> Role:
    """The role of a class name (unknown names are people: module docstring); cached, since
    the confirmation asks it of every sighting every frame."""
    key = normalise_class(name)
    if key in APPLIANCE_CLASSES:
        return "appliance"
    if key in OBJECT_CLASSES:
        return "object"
    return "person"


def roles(classes: Sequence[str]) -> tuple[Role, ...]:
    """The role of each class, index = class id."""
    return tuple(role_of(c) for c in classes)


def person_class_ids(classes: Sequence[str]) -> np.ndarray:
    """Indices of the classes that are people."""
    return np.array([i for i, c in enumerate(classes) if role_of(c) == "person"], np.int64)


#: Names an operator reads on a 50-byte STATUSTEXT and a map marker, where the class name is long.
SHORT_LABELS: dict[str, str] = {
    "life_saving_appliances": "life ring",
    "life_saving_appliance": "life ring",
}


def short_label(name: str) -> str:
    """The class's name as an operator reads it (``life_saving_appliances`` -> ``life ring``)."""
    return SHORT_LABELS.get(normalise_class(name), name)


def class_name(classes: Sequence[str], class_id: int, unknown: str = "") -> str:
    """Class ``class_id`` of ``classes``, or ``unknown`` for an id outside them."""
    return classes[class_id] if 0 <= class_id < len(classes) else unknown


def role_of_id(classes: Sequence[str], class_id: int) -> Role:
    """The role of class ``class_id`` of ``classes`` (an id outside them: a person)."""
    return role_of(class_name(classes, class_id))
