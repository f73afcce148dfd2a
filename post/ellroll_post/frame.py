"""An ellroll file's cases as a pandas DataFrame: one row per case."""
import numpy as np

from .reader import open as open_run


def summary_frame(path):
    """A pandas DataFrame of one row per case, indexed by the global case
    index (`case`): every input of /case (a vector's components as their
    input names, `omega_z`; text as str), `status` by name (categorical,
    its categories the file's flag_meanings, and `unknown` for a code outside
    them), then every figure of /summary
    (a value per mode as a column per mode, `linear_periods_1`, as in
    `ellroll summary --format csv`; a count as pandas' nullable Int64,
    missing (<NA>) where it holds the dataset's _FillValue, -1: a case
    never run). Units are in `frame.attrs["units"]`, column by column."""
    import pandas as pd
    with open_run(path) as run:
        h5 = run._h5
        columns, units = {}, {}
        for name, dataset in h5["case"].items():
            if name in ("case", "index"):
                continue
            values = dataset[:]
            if dataset.dtype.kind in "OS":
                values = np.array([v.decode() if isinstance(v, bytes) else v for v in values], dtype=object)
            names = dataset.attrs.get("input_names", name).split()
            if values.ndim == 1:
                columns[names[0]] = values
                units[names[0]] = dataset.attrs.get("units", "")
            else:
                for k in range(values.shape[1]):
                    label = names[k] if k < len(names) else f"{name}_{k + 1}"
                    columns[label] = values[:, k]
                    units[label] = dataset.attrs.get("units", "")
        status = h5["summary/status"]
        order = np.argsort(status.attrs["flag_values"])
        categories = list(np.array(status.attrs["flag_meanings"].split())[order])
        names = run.status_names()
        if "unknown" in names and "unknown" not in categories:
            categories.append("unknown")   # a code outside flag_values (reader.status_names)
        columns["status"] = pd.Categorical(names, categories=categories)
        units["status"] = "1"
        for name in run.summary_figures:
            values, unit = run.summary(name), run.units(f"summary/{name}")
            fill = h5[f"summary/{name}"].attrs.get("_FillValue")
            if values.dtype.kind in "iu" and fill is not None and values.ndim == 1:
                values = pd.array(values, dtype="Int64")
                values[np.asarray(values == np.asarray(fill).ravel()[0], dtype=bool)] = pd.NA
            if values.ndim == 1:
                columns[name], units[name] = values, unit
            else:
                for m in range(values.shape[1]):
                    columns[f"{name}_{m + 1}"], units[f"{name}_{m + 1}"] = values[:, m], unit
        frame = pd.DataFrame(columns, index=pd.Index(run.summary("case"), name="case"))
    frame.attrs["units"] = units
    return frame
