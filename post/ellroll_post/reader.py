"""Lazy access to an ellroll file: nothing is read until asked for."""

import h5py


class NotAnEllrollFile(Exception):
    """The file is missing, unreadable, or was not written by ellroll."""


class EllrollFile:
    def __init__(self, path):
        self.path = str(path)
        try:
            self._h5 = h5py.File(self.path, "r")
        except OSError as exc:
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

    @property
    def n_cases(self):
        return self._h5["summary/status"].shape[0]

    @property
    def time(self):
        return self._h5["time"][:]

    def _dataset(self, name):
        if name not in self._h5:
            raise NotAnEllrollFile(f"{self.path}: no dataset /{name} in this file")
        return self._h5[name]

    def _check_case(self, case):
        if not 0 <= case < self.n_cases:
            raise IndexError(f"{self.path}: case {case} out of range (0..{self.n_cases - 1})")

    def trajectory(self, field, case=0):
        """One case's samples of a trajectory field: (nt,) or (nt, 3)."""
        self._check_case(case)
        return self._dataset(f"trajectory/{field}")[case]

    def case_input(self, name, case=0):
        self._check_case(case)
        value = self._dataset(f"case/{name}")[case]
        return value.decode() if isinstance(value, bytes) else value

    def summary(self, name, case=None):
        ds = self._dataset(f"summary/{name}")
        if case is None:
            return ds[:]
        self._check_case(case)
        return ds[case]

    def status_name(self, case=0):
        ds = self._dataset("summary/status")
        names = ds.attrs["flag_meanings"].split()
        values = list(ds.attrs["flag_values"])
        return names[values.index(int(self.summary("status", case)))]

    def units(self, name):
        return self._dataset(name).attrs.get("units", "")


def open(path):  # noqa: A001 - mirrors h5py.File / xarray.open_dataset naming
    """Open an ellroll file for reading."""
    return EllrollFile(path)


