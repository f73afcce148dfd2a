"""Every ellroll-plot command and the report on a sampled campaign of 10,000
cases: the figures are written and the memory stays bounded (the times are
in bench/plots.py, not here)."""
import subprocess
import sys

import pytest

from conftest import run

CAMPAIGN = """&geometry a = 1.0, b = 0.4, c = 0.2 /
&ball radius = 0.2, weight = 2620.0 /
&initial omega = -2.0, 2.0, 20.0 /
&integration method = 'rk4', dt = 1.0e-3, t_end = 0.2 /
&output file = 'campaign.h5', interval = 0.01 /
&campaign samples = 10000, seed = 7 /
&sample name = 'omega_z', low = 5, high = 50 /
&sample name = 'radius', low = 0.05, high = 0.2 /
&sample name = 'x', low = -0.1, high = 0.1 /
&sample name = 'y', low = -0.05, high = 0.05 /
&sample name = 'mu', low = 0.1, high = 0.5 /
"""
# a 10^4-case heat map of distinct-value pairs took 23 GiB; a figure needs
# far less than this whatever the number of cases
PEAK_MIB = 1024


@pytest.mark.parametrize("args, written", [
    (["trace"], ["campaign_fig2_trace.png"]), (["sweep"], ["campaign_sweep_radius_mu.png"]),
    (["sweep", "--x", "omega_z"], ["campaign_sweep_omega_z.png"]),
    (["report"], ["index.html", "summary.csv", "campaign_sweep_radius.png", "campaign_energy.png"])])
def test_campaign_figures_in_bounded_memory(ellroll, tmp_path_factory, args, written):
    folder = tmp_path_factory.getbasetemp() / "campaign10k"
    if not (folder / "campaign.h5").exists():
        folder.mkdir(exist_ok=True)
        (folder / "campaign.nml").write_text(CAMPAIGN)
        result = run(ellroll, "run", "campaign.nml", "-q", cwd=folder, timeout=600)
        assert result.returncode == 0, result.stderr
    out = folder / "_".join(args)
    command = [sys.executable, "-c", "import resource, sys; from ellroll_post.cli import main; code = main(sys.argv[1:]); "
               "print(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss // 1024, file=sys.stderr); sys.exit(code)",
               *args, "campaign.h5", "--out", str(out)]
    result = subprocess.run(command, cwd=folder, capture_output=True, text=True, timeout=600)
    assert result.returncode == 0, result.stderr
    assert int(result.stderr.split()[-1]) < PEAK_MIB
    for name in written:
        assert (out / name).stat().st_size > 0, name
