"""What every component shares: an instance label beside its registry name, and the check that it implements its protocol."""

from __future__ import annotations

from typing import Any, ClassVar


class Labelled:
    """An instance label, separate from the registry name.

    ``name`` (class attribute) is the registry name; ``label`` names this
    instance in a run (result keys, recorded entity paths) and defaults to
    ``name``, so two instances of one class with different parameters coexist
    (``("signal_function", {"window": 10}, "sf10")`` or ``det.label = "sf10"``).
    """

    name: ClassVar[str]

    @property
    def label(self) -> str:
        return self.__dict__.get("_label") or self.name

    @label.setter
    def label(self, value: str) -> None:
        if not isinstance(value, str) or not value.strip() or "/" in value:
            raise ValueError(f"label: expected a non-empty name without '/', got {value!r}")
        self.__dict__["_label"] = value


def require(component: Any, protocol: type, role: str) -> Any:
    """``component`` if it implements ``protocol`` (an interface or protocol ABC), else a TypeError naming what is missing.

    ``role`` names the argument (e.g. ``"detector"``).  The message lists the
    protocol's methods and declared attributes the object lacks, so a plugin
    author learns from it what to implement.
    """
    if isinstance(component, protocol):
        return component
    wanted = sorted(getattr(protocol, "__abstractmethods__", ())) + list(getattr(protocol, "declared_attributes", ()))
    missing = [m for m in wanted if not hasattr(component, m)]
    what = f"; it lacks {', '.join(missing)}" if missing else ""
    raise TypeError(
        f"{role}: {type(component).__name__} does not implement {protocol.__module__}.{protocol.__name__}"
        f" (subclass it and implement {', '.join(wanted) or 'its methods'}){what}"
    )
