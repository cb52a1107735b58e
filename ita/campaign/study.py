"""A campaign file: a study of many inspection runs, described in TOML.

    [campaign]
    name = "grr"             # default: the file's stem
    limit = 40               # measurements per run: the first N of each part's sequence (default: all)
    faults = 0.0             # fault rate per command (ita inspect --faults)
    fault_kinds = []         # the kinds it draws from (default: all injectable)
    arms = 1                 # 2: both arms of the part's workcell work each run (ita inspect --arms 2)

    [parts]
    seeds = [11, 12, 13]     # one part per generator seed (ita part new DIR --seed S)
    params = "small.toml"    # optional: the bulkhead generator's parameters, relative to this file

    [appraisers]
    seeds = [1, 2, 3]        # each appraiser a simulated cell of its own seed
    trials = 3               # runs per part and appraiser

The runs are every part x appraiser x trial (a crossed gauge R&R study, AIAG MSA); run
(part S, appraiser A, trial T) is `ita inspect --part PART_S --seed N` with N drawn from
the three (:func:`sim_seed`), so no two runs share their noise.  :func:`load_campaign` checks every table and key and raises InputError
naming the file and the field.
"""

from __future__ import annotations

import hashlib
import json
import tomllib
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

from ita.errors import InputError, Location
from ita.part.params import BulkheadParams
from ita.seeds import SEED_MAX

__all__ = ["MAX_RUNS", "Campaign", "RunTask", "load_campaign"]

#: runs a campaign may ask for (parts x appraisers x trials); a larger one is refused before anything is made
MAX_RUNS = 100_000
#: a campaign file is a few lines; a larger one is refused before it is parsed
MAX_FILE_BYTES = 1 << 20

def sim_seed(part_seed: int, appraiser: int, trial: int) -> int:
    """The simulator's seed of a run: a digest of its part, appraiser and trial (31 bits)."""
    digest = hashlib.sha256(f"ita-campaign/{part_seed}/{appraiser}/{trial}".encode()).digest()
    return int.from_bytes(digest[:4], "big") & 0x7FFFFFFF


@dataclass(frozen=True)
class RunTask:
    """One inspection run of a campaign, as a worker needs it (plain values only, so it
    travels to a process pool or a cluster): key: its name in the campaign archive;
    part_dir/home: the part and a prepared ITA_HOME on the machine that made them (a
    worker without them makes the part again from part_seed and params_text);
    sim_seed: the simulator's seed."""

    key: str
    part_seed: int
    appraiser: int
    trial: int
    sim_seed: int
    limit: int | None
    faults: float
    fault_kinds: tuple[str, ...]
    params_text: str | None
    part_dir: str
    home: str
    arms: int = 1

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)

    def settings(self) -> str:
        """What makes the run what it is (not where its files are): a restarted campaign
        whose file changed these is refused."""
        d = {k: v for k, v in asdict(self).items() if k not in ("part_dir", "home")}
        if d["arms"] == 1:
            del d["arms"]            # a one-arm campaign keeps the settings it was started with
        return json.dumps(d, sort_keys=True)


@dataclass(frozen=True)
class Campaign:
    """A parsed campaign file (see the module doc)."""

    name: str
    source: Path
    part_seeds: tuple[int, ...]
    params_path: Path | None
    appraisers: tuple[int, ...]
    trials: int
    limit: int | None
    faults: float
    fault_kinds: tuple[str, ...]
    arms: int = 1

    @property
    def params_text(self) -> str | None:
        return None if self.params_path is None else self.params_path.read_text(encoding="utf-8")

    def part_key(self, seed: int) -> str:
        """The directory name of part `seed` (its parameters' digest in it: other
        parameters, another part)."""
        text = self.params_text or ""
        return f"part-{seed}-{hashlib.sha256(text.encode()).hexdigest()[:8]}"

    def tasks(self, out_dir: Path) -> list[RunTask]:
        """Every run, in order part, appraiser, trial."""
        out = []
        text = self.params_text
        for p in self.part_seeds:
            key = self.part_key(p)
            for a in self.appraisers:
                for t in range(1, self.trials + 1):
                    out.append(RunTask(f"p{p}-a{a}-t{t}", p, a, t, sim_seed(p, a, t), self.limit, self.faults,
                                       self.fault_kinds, text, str(out_dir / "parts" / key),
                                       str(out_dir / "homes" / key), self.arms))
        return out


def _ints(value: Any, loc: Location, what: str, minimum: int = 0, maximum: int = SEED_MAX) -> tuple[int, ...]:
    if not isinstance(value, list) or not value or not all(isinstance(v, int) and not isinstance(v, bool)
                                                           and minimum <= v <= maximum for v in value):
        raise InputError([(loc, f"{what}: a non-empty list of integers from {minimum} to {maximum}")])
    if len(set(value)) != len(value):
        raise InputError([(loc, f"{what}: a seed is listed twice")])
    return tuple(value)


def load_campaign(path: Path) -> Campaign:
    """The campaign in `path`; InputError naming the file and the field when it is bad."""
    path = Path(path)
    loc = Location(str(path))
    if not path.is_file():
        raise InputError([(loc, "campaign file not found")])
    if path.stat().st_size > MAX_FILE_BYTES:
        raise InputError([(loc, f"{path.stat().st_size:,} bytes: a campaign file is at most {MAX_FILE_BYTES:,} "
                                f"(it asks for at most {MAX_RUNS:,} runs)")])
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise InputError([(loc, f"not valid TOML: {exc}")]) from None
    known = {"campaign": {"name", "limit", "faults", "fault_kinds", "arms"}, "parts": {"seeds", "params"},
             "appraisers": {"seeds", "trials"}}
    problems = []
    for table, keys in data.items():
        if table not in known:
            problems.append((Location(str(path), field=table), f"unknown table [{table}] (known: {', '.join(known)})"))
        elif not isinstance(keys, dict):
            problems.append((Location(str(path), field=table), "must be a table"))
        else:
            problems += [(Location(str(path), field=f"{table}.{k}"), "unknown key") for k in keys if k not in known[table]]
    for table in ("parts", "appraisers"):
        if table not in data:
            problems.append((Location(str(path), field=table), f"missing table [{table}]"))
    if problems:
        raise InputError(problems)
    c, parts, appr = data.get("campaign", {}), data["parts"], data["appraisers"]

    def field(name: str) -> Location:
        return Location(str(path), field=name)

    part_seeds = _ints(parts.get("seeds"), field("parts.seeds"), "parts.seeds")
    appraisers = _ints(appr.get("seeds"), field("appraisers.seeds"), "appraisers.seeds")
    trials = appr.get("trials", 1)
    if not isinstance(trials, int) or isinstance(trials, bool) or not 1 <= trials < 1000:
        raise InputError([(field("appraisers.trials"), "an integer from 1 to 999")])
    runs = len(part_seeds) * len(appraisers) * trials
    if runs > MAX_RUNS:
        raise InputError([(field("parts.seeds x appraisers.seeds x appraisers.trials"),
                           f"{len(part_seeds):,} x {len(appraisers):,} x {trials} = {runs:,} runs; a campaign "
                           f"runs at most {MAX_RUNS:,}")])
    params_path = None
    if "params" in parts:
        if not isinstance(parts["params"], str):
            raise InputError([(field("parts.params"), "a path to a bulkhead parameter file (TOML)")])
        params_path = (path.parent / parts["params"]).resolve()
        if not params_path.is_file():
            raise InputError([(field("parts.params"), f"{params_path}: not found")])
        BulkheadParams.load(params_path)        # its own errors name its own fields
    limit = c.get("limit")
    if limit is not None and (not isinstance(limit, int) or isinstance(limit, bool) or limit < 1):
        raise InputError([(field("campaign.limit"), "a positive integer (measurements per run)")])
    faults = c.get("faults", 0.0)
    if not isinstance(faults, (int, float)) or isinstance(faults, bool) or not 0.0 <= faults <= 1.0:
        raise InputError([(field("campaign.faults"), "a rate from 0 to 1")])
    kinds = c.get("fault_kinds", [])
    if not isinstance(kinds, list) or not all(isinstance(k, str) for k in kinds):
        raise InputError([(field("campaign.fault_kinds"), "a list of fault kinds (see ita inspect --help)")])
    arms = c.get("arms", 1)
    if arms not in (1, 2) or isinstance(arms, bool):
        raise InputError([(field("campaign.arms"), "1 or 2 (how many of the workcell's arms work each run)")])
    name = c.get("name", path.stem)
    if not isinstance(name, str) or not name.strip():
        raise InputError([(field("campaign.name"), "a non-empty string")])
    return Campaign(name, path.resolve(), part_seeds, params_path, appraisers, trials, limit, float(faults),
                    tuple(kinds), arms)
