"""Lazy access to an ellroll file: nothing is read until asked for, so a
file of 10^5 cases costs only what is plotted."""
import os

import h5py
import numpy as np


class NotAnEllrollFile(Exception):
    """The file is missing, unreadable, not written by ellroll, or lacks what is asked."""


class EllrollFile:
    def __init__(self, path):
        self.path = str(path)
        if os.path.isdir(self.path):
            raise NotAnEllrollFile(f"{self.path}: a folder, not an ellroll file")
        try:
            self._h5 = h5py.File(self.path, "r")
        except (OSError, ValueError) as exc:
            raise NotAnEllrollFile(f"{self.path}: cannot open as HDF5 ({exc})") from None
        if self._h5.attrs.get("program") != "ellroll":
            self._h5.close()
            raise NotAnEllrollFile(f"{self.path}: not an ellroll file (no program='ellroll' attribute)")

    def close(self):
        self._h5.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    # ---------------------------------------------------------- layout
    @property
    def attrs(self):
        return dict(self._h5.attrs)

    @property
    def n_cases(self):
        return self._dataset("summary/status").shape[0]

    @property
    def time(self):
        return self._dataset("time")[:]

    @property
    def fields(self):
        return sorted(set(self._h5["trajectory"]) - {"case", "time"} - set(self._coordinates("trajectory")))

    @property
    def summary_names(self):
        return sorted(self.summary_figures)

    @property
    def summary_figures(self):
        """The figures of /summary in the file's order (its members are kept
        in the order they were made, the order of ellroll's summary table),
        without the case index, the status, the checksum and the varied
        inputs."""
        return [n for n in self._h5["summary"]
                if n not in {"case", "status", "checksum", *self._coordinates("summary")}]

    def _coordinates(self, group):
        """The varied inputs a group holds as coordinates of its cases (CF's
        `coordinates` attribute, the same on each of its variables)."""
        for item in self._h5[group].values():
            if "coordinates" in item.attrs:
                return item.attrs["coordinates"].split()
        return []

    def _dataset(self, name):
        if name not in self._h5:
            raise NotAnEllrollFile(f"{self.path}: no dataset /{name} in this file")
        return self._h5[name]

    def check_case(self, case):
        if not 0 <= case < self.n_cases:
            raise NotAnEllrollFile(f"{self.path}: case {case} out of range (the file has cases 0..{self.n_cases - 1})")

    def units(self, name):
        return self._dataset(name).attrs.get("units", "")

    # ------------------------------------------------------------ data
    def trajectory(self, field, case=0):
        """One case's samples of a trajectory field: (nt,) or (nt, 3)."""
        self.check_case(case)
        return self._dataset(f"trajectory/{field}")[case]

    @property
    def inputs(self):
        """{input: (/case dataset, component or None)}: every input the file
        holds, named as a sweep names it (omega_z), in the file's order. Each
        /case dataset of inputs names them in its `input_names` attribute,
        one per component; a file written before that attribute gives its
        real /case datasets of one value per case under their own names."""
        if not hasattr(self, "_inputs"):
            group = self._h5["case"]
            named = {d: v.attrs["input_names"].split() for d, v in group.items() if "input_names" in v.attrs}
            if not named:
                named = {d: [d] for d, v in group.items() if v.dtype.kind == "f" and v.ndim == 1}
            self._inputs = {name: (dataset, component if len(names) > 1 else None)
                            for dataset, names in named.items() for component, name in enumerate(names)}
        return self._inputs

    def _input(self, name):
        """(/case dataset, component) of an input, by its name (omega_z) or
        its /case dataset's (omega)."""
        return self.inputs.get(name, (name, None))

    def case_input(self, name, case=0):
        """A resolved input of one case, by its name (omega_z) or /case name (omega)."""
        self.check_case(case)
        dataset, component = self._input(name)
        value = self._dataset(f"case/{dataset}")[case]
        if component is not None:
            value = value[component]
        return value.decode() if isinstance(value, bytes) else value

    def input_units(self, name):
        """The units of an input, by its name (omega_z) or /case name."""
        return self.units("case/" + self._input(name)[0])

    def input_column(self, name):
        """An input over all cases (for sweeps)."""
        dataset, component = self._input(name)
        values = self._dataset(f"case/{dataset}")
        return values[:, component] if component is not None else values[:]

    def swept_inputs(self):
        """The inputs that differ between cases, by name."""
        if self.n_cases < 2:
            return []
        # a file still being written (OUT.h5.partial) has no inputs yet for its pending cases
        written = np.array(self.status_names()) != "pending"
        if written.sum() < 2:
            return []
        swept = []
        for name in self.inputs:
            column = self.input_column(name)[written]
            # NaN (an input left unset) is the same as NaN: unset in every case is not varied
            same = (column == column[0]) | (np.isnan(column) & np.isnan(column[0]))
            if not np.all(same):
                swept.append(name)
        if "weight" in swept and "mass" in swept:
            swept.remove("mass" if np.unique(self.input_column("g")).size == 1 else "weight")
        return swept

    def varied_inputs(self):
        """The inputs that vary between the cases, as the file names its
        coordinates (sweeps, samples, then a suite's record); for a file
        without them, the inputs that differ (swept_inputs) and the record."""
        return self._coordinates("summary") or self.swept_inputs() + (["record"] if any(self.record_names()) else [])

    def record_names(self):
        """Each case's record of a suite (&record name), or blanks."""
        if "case/record" not in self._h5:
            return [""] * self.n_cases
        return [n.decode().strip() if isinstance(n, bytes) else str(n).strip() for n in self._h5["case/record"][:]]

    def summary(self, name, case=None):
        ds = self._dataset(f"summary/{name}")
        if case is None:
            return ds[:]
        self.check_case(case)
        return ds[case]

    def switches(self, case=0):
        """One case's switches of regime, in order: (times in s, kinds by
        name, 'to_sliding' or 'to_rolling'), from /switches (a campaign
        with &ball slip = 'slide'); empty for a case that never slid."""
        self.check_case(case)
        if "switches" not in self._h5:
            raise NotAnEllrollFile(f"{self.path}: no /switches in this file (no case may slide: "
                                   "&ball slip = 'slide' stores them)")
        group = self._h5["switches"]
        first, count = int(group["first"][case]), int(group["count"][case])
        if count < 0:
            raise ValueError(f"{self.path}: case {case} was never run ({self.status_name(case)})")
        kinds = group["switch_kind"]
        values = np.asarray(kinds.attrs["flag_values"])
        names = np.array(kinds.attrs["flag_meanings"].split())
        codes = kinds[first:first + count]
        return group["switch_time"][first:first + count], names[np.searchsorted(values, codes)]

    def status_names(self):
        """Each case's status by name (the flag_meanings of its flag_values)."""
        return self._status_meanings(self._dataset("summary/status")[:]).tolist()

    def status_name(self, case=0):
        self.check_case(case)
        return str(self._status_meanings(self._dataset("summary/status")[case:case + 1])[0])

    def _status_meanings(self, codes):
        """The flag_meanings of codes; "unknown" for a code outside flag_values (a file
        from a later version, or altered), as `ellroll summary` names and counts it."""
        attrs = self._dataset("summary/status").attrs
        values = np.asarray(attrs["flag_values"])
        order = np.argsort(values)
        names = np.array(attrs["flag_meanings"].split())[order]
        codes = np.asarray(codes)
        at = np.minimum(np.searchsorted(values[order], codes), len(values) - 1)
        return np.where(values[order][at] == codes, names[at], "unknown")


def open(path):  # noqa: A001 - mirrors h5py.File / xarray.open_dataset naming
    """Open an ellroll file for reading."""
    return EllrollFile(path)
