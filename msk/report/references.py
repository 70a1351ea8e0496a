"""The literature the report cites, and its numbering.

A section cites a work by key (:meth:`Citations.cite`, ``{{ cite("hicks2015") }}`` in a
template); the first citation of a work gives it the next number, so the numbers run 1, 2, 3 …
in the order the report first cites them, and the reference list (section ``references``) holds
exactly the works cited, each with its authors (where the copy of the paper we hold names them)
and year.
"""

from __future__ import annotations

import re

__all__ = ["LITERATURE", "Citations", "cite_internal_names"]

#: key → full reference (authors, year, title, source)
LITERATURE: dict[str, str] = {
    "hayashibe2011": "Hayashibe M, Venture G, Ayusawa K, Nakamura Y (2011). Muscle strength and "
    "mass distribution identification toward subject-specific musculoskeletal modeling.",
    "benoussaad2013": "Benoussaad M et al. (2013). Experimental parameter identification of a "
    "multi-scale musculoskeletal model controlled by electrical stimulation: application to "
    "patients with spinal cord injury.",
    "thesis": "Using subject-specific muscle parameters to compare muscle forces and activation "
    "between an EMG-driven and OpenSim musculoskeletal model (master's thesis; author and year "
    "not given in our copy).",
    "rehab_model": "A computationally efficient musculoskeletal model of the lower limb for the "
    "control of rehabilitation robots: assumptions and validation (authors and year not given "
    "in our copy).",
    "hicks2015": "Hicks JL, Uchida TK, Seth A, Rajagopal A, Delp SL (2015). Is my model good "
    "enough? Best practices for verification and validation of musculoskeletal models and "
    "simulations of movement. J Biomech Eng 137:020905.",
    "delp1990": "Delp SL, Loan JP, Hoy MG, Zajac FE, Topp EL, Rosen JM (1990). An interactive "
    "graphics-based model of the lower extremity to study orthopaedic surgical procedures. "
    "IEEE Trans Biomed Eng 37:757–767.",
    "dumas2007": "Dumas R, Chèze L, Verriest JP (2007). Adjustments to McConville et al. and "
    "Young et al. body segment inertial parameters. J Biomech 40:543–553.",
    "kutzner2010": "Kutzner I, Heinlein B, Graichen F, Bender A, Rohlmann A, Halder A, Beier A, "
    "Bergmann G (2010). Loading of the knee joint during activities of daily living measured "
    "in vivo in five subjects. J Biomech 43:2164–2173.",
    "vaneijden1986": "van Eijden TMGJ, Kouwenhoven E, Verburg J, Weijs WA (1986). A "
    "mathematical model of the patellofemoral joint. J Biomech 19:219–229.",
    "fregly2012": "Fregly BJ, Besier TF, Lloyd DG, Delp SL, Banks SA, Pandy MG, D'Lima DD "
    "(2012). Grand challenge competition to predict in vivo knee loads. J Orthop Res "
    "30:503–513.",
    "kadaba1990": "Kadaba MP, Ramakrishnan HK, Wootten ME (1990). Measurement of lower "
    "extremity kinematics during level walking. J Orthop Res 8:383–392.",
    "davis1991": "Davis RB, Õunpuu S, Tyburski D, Gage JR (1991). A gait analysis data "
    "collection and reduction technique. Hum Mov Sci 10:575–587.",
    "winter2009": "Winter DA (2009). Biomechanics and motor control of human movement, 4th ed. "
    "Wiley.",
}

#: internal document names that can appear in strings of a run (method names, messages) → the
#: work they are
_INTERNAL = {
    "seeds/000": "benoussaad2013",
    "seeds/002": "hayashibe2011",
    "seeds/003": "thesis",
    "seeds/004": "rehab_model",
}
_WORDS = {
    "benoussaad2013": "Benoussaad et al. 2013",
    "hayashibe2011": "Hayashibe et al. 2011",
    "thesis": "the EMG-driven vs OpenSim thesis",
    "rehab_model": "the rehabilitation-robot lower-limb model paper",
}


def cite_internal_names(text: str) -> str:
    """``text`` with internal document names (``seeds/00N``) replaced by the work's name."""
    if "seeds/" not in text:
        return text

    def name(m: re.Match[str]) -> str:
        key = _INTERNAL.get(m.group(0))
        return _WORDS[key] if key else "a companion FES identification study"

    return re.sub(r"seeds/00\d", name, text)


class Citations:
    """The numbering of one report: ``cite(key)`` → ``"[n]"``, n given at the first citation."""

    def __init__(self) -> None:
        self._order: list[str] = []

    def cite(self, *keys: str) -> str:
        nums = []
        for key in keys:
            if key not in LITERATURE:
                raise KeyError(f"no reference {key!r} in msk.report.references.LITERATURE")
            if key not in self._order:
                self._order.append(key)
            nums.append(str(self._order.index(key) + 1))
        return "[" + ", ".join(nums) + "]"

    def number(self, key: str) -> int:
        """The number of ``key`` (citing it if it was not yet)."""
        self.cite(key)
        return self._order.index(key) + 1

    @property
    def cited(self) -> list[tuple[int, str]]:
        """(number, reference) of every work cited, in number order."""
        return [(k + 1, LITERATURE[key]) for k, key in enumerate(self._order)]
