"""Lazy access to an ellroll file: nothing is read until asked for, so a
file of 10^5 cases costs only what is plotted."""
import h5py
import numpy as np


class NotAnEllrollFile(Exception):
    """The file is missing, unreadable, not written by ellroll, or lacks what is asked."""


# inputs as the namelist names them -> (/case dataset, component)
INPUTS = {"a": ("a", None), "b": ("b", None), "c": ("c", None), "radius": ("radius", None),
          "weight": ("weight", None), "mass": ("mass", None), "mu": ("mu", None),
          "inertia_factor": ("inertia_factor", None), "g": ("g", None), "x": ("x", None), "y": ("y", None),
          "omega_x": ("omega", 0), "omega_y": ("omega", 1), "omega_z": ("omega", 2), "dt": ("dt", None),
          "fit_margin": ("fit_margin", None), "rtol": ("rtol", None), "atol": ("atol", None),
          "excitation_frequency": ("excitation_frequency", None), "excitation_phase": ("excitation_phase", None),
          "excitation_amplitude_x": ("excitation_amplitude", 0), "excitation_amplitude_y": ("excitation_amplitude", 1),
          "excitation_amplitude_z": ("excitation_amplitude", 2), "scale": ("scale", None),
          "rolling_resistance": ("rolling_resistance", None)}
# the other /case names a file may give these inputs (ellroll 0.1.0 files), read as the same
ALIASES = {"case/x": "case/x0", "case/y": "case/y0", "case/omega": "case/omega0"}


class EllrollFile:
    def __init__(self, path):
        self.path = str(path)
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
        return sorted(set(self._h5["trajectory"]) - {"case"} - set(self._coordinates("trajectory")))

    @property
    def summary_names(self):
        return sorted(set(self._h5["summary"]) - {"case"} - set(self._coordinates("summary")))

    def _coordinates(self, group):
        """The varied inputs a group holds as coordinates of its cases (CF's
        `coordinates` attribute, the same on each of its variables)."""
        for item in self._h5[group].values():
            if "coordinates" in item.attrs:
                return item.attrs["coordinates"].split()
        return []

    def _dataset(self, name):
        if name not in self._h5 and ALIASES.get(name) in self._h5:
            name = ALIASES[name]
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

    def case_input(self, name, case=0):
        """A resolved input of one case, by its namelist name (omega_z) or /case name (omega0)."""
        self.check_case(case)
        dataset, component = INPUTS.get(name, (name, None))
        value = self._dataset(f"case/{dataset}")[case]
        if component is not None:
            value = value[component]
        return value.decode() if isinstance(value, bytes) else value

    def input_units(self, name):
        """The units of an input, by its namelist name (omega_z) or /case name."""
        return self.units("case/" + INPUTS.get(name, (name, None))[0])

    def input_column(self, name):
        """An input over all cases (for sweeps)."""
        dataset, component = INPUTS.get(name, (name, None))
        values = self._dataset(f"case/{dataset}")
        return values[:, component] if component is not None else values[:]

    def swept_inputs(self):
        """The inputs that differ between cases, in namelist names."""
        if self.n_cases < 2:
            return []
        swept = []
        for name in INPUTS:
            dataset, _ = INPUTS[name]
            if f"case/{dataset}" not in self._h5 and ALIASES.get(f"case/{dataset}") not in self._h5:
                continue
            column = self.input_column(name)
            if np.unique(column[np.isfinite(column)]).size > 1:
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

    def status_names(self):
        """Each case's status by name (the flag_meanings of its flag_values)."""
        return self._status_meanings(self._dataset("summary/status")[:]).tolist()

    def status_name(self, case=0):
        self.check_case(case)
        return str(self._status_meanings(self._dataset("summary/status")[case:case + 1])[0])

    def _status_meanings(self, codes):
        attrs = self._dataset("summary/status").attrs
        values = np.asarray(attrs["flag_values"])
        order = np.argsort(values)
        names = np.array(attrs["flag_meanings"].split())[order]
        return names[np.searchsorted(values[order], codes)]


def open(path):  # noqa: A001 - mirrors h5py.File / xarray.open_dataset naming
    """Open an ellroll file for reading."""
    return EllrollFile(path)
