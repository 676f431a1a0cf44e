"""Every derivation of the course, by name, in course order.

The registry knows the topic modules (:data:`TOPICS`, in course order) and lists, in each
one, the functions marked by :func:`~kalman_course.symbolic.equations.derivation_builder`,
in the order the module defines them. A new derivation is registered by writing its
builder with that decorator in a topic module; a new topic module is added to
:data:`TOPICS`. Nothing depends on which module happened to be imported first.
"""

from __future__ import annotations

import functools
import types
from typing import Callable, Mapping

from kalman_course.symbolic import eskf, gaussians, kalman, motion, radar
from kalman_course.symbolic.equations import Derivation

__all__ = ["TOPICS", "builders", "derivations", "derivation"]

#: The modules that define derivations, in course order (chapters 02, 03, 04, 05, 08).
TOPICS: tuple[types.ModuleType, ...] = (gaussians, kalman, motion, radar, eskf)


@functools.cache
def builders() -> Mapping[str, Callable[[], Derivation]]:
    """Return every derivation builder, keyed by derivation name, in course order.

    Returns
    -------
    mapping of str to callable
        Read-only; each value is a cached builder taking no arguments.

    Raises
    ------
    RuntimeError
        If two topic modules define a builder of the same name.
    """
    found: dict[str, Callable[[], Derivation]] = {}
    for topic in TOPICS:
        for obj in vars(topic).values():
            name = getattr(obj, "derivation_name", None)
            # a builder imported from another module is listed where it is defined
            if name is None or obj.__module__ != topic.__name__:
                continue
            if name in found:
                raise RuntimeError(f"two derivation builders are named {name!r}: in "
                                   f"{found[name].__module__} and in {topic.__name__}")
            found[name] = obj
    return types.MappingProxyType(found)


def derivations() -> dict[str, Derivation]:
    """Return every derivation of the course, keyed by name, in course order.

    Each derivation is built (SymPy) on the first call and cached; later calls return the
    same objects.
    """
    return {name: build() for name, build in builders().items()}


def derivation(name: str) -> Derivation:
    """Return the derivation called ``name``.

    Raises
    ------
    ValueError
        If ``name`` is not a string or there is no such derivation; the message lists the
        known names.
    """
    known = builders()
    if not isinstance(name, str):
        raise ValueError(f"name must be the name (str) of a derivation, one of {list(known)}; got {name!r}")
    if name not in known:
        raise ValueError(f"name: unknown derivation {name!r}; known: {list(known)}")
    return known[name]()
