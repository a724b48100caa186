"""Plausible wrong answers to the course's exercises, shared by tests/test_course.py and the
``executed_notebook`` fixture of conftest.py (which runs each check on them)."""

#: One plausible wrong answer per exercise; each replaces the marked answer of its cell.
WRONG = {
    # degrees given to np.cos
    "01.1": "def flux_ratio(alpha_deg, beta_deg):\n"
            "    return np.cos(alpha_deg) * np.cos(beta_deg)",
    # the derivative per radian, not per degree
    "01.2": "def px_per_degree(alpha_deg):\n"
            "    return F / p / np.cos(np.radians(alpha_deg)) ** 2",
    # an off-by-one window: rows r-3 .. r+1 instead of r-2 .. r+2
    "02.1": "def window_search(frame, size=5, need=18):\n"
            "    f = np.asarray(frame, dtype=float)\n"
            "    border = np.zeros(f.shape, bool)\n"
            "    border[:2], border[-2:], border[:, :2], border[:, -2:] = True, True, True, True\n"
            "    i_m = f[border].mean()\n"
            "    above = f > 3 * i_m\n"
            "    windows = np.lib.stride_tricks.sliding_window_view(np.pad(above, 2), (5, 5))\n"
            "    counts = np.roll(windows.sum(axis=(2, 3)), 1, axis=0)\n"
            "    ok = above & (counts >= need)\n"
            "    ok[[0, -1], :] = False\n"
            "    ok[:, [0, -1]] = False\n"
            "    row, col = np.argwhere(ok)[0]\n"
            "    return i_m, int(row), int(col)",
    # the signal not clipped at the threshold: the background below it pulls the centre
    "02.2": "def centre_of_mass(img, threshold):\n"
            "    w = np.asarray(img, dtype=float) - threshold\n"
            "    rows, cols = np.indices(w.shape)\n"
            "    return float((w * cols).sum() / w.sum()), float((w * rows).sum() / w.sum())",
    # the Fisher information of a Gaussian of constant variance: mu^2 for mu
    "02.3": "def photon_crlb(n_e, b_e, radius, edge, s=8):\n"
            "    h = int(np.ceil(radius + edge + 3))\n"
            "    centres = np.arange(-h, h + 1)\n"
            "    grid = (centres[:, None] + (np.arange(s) + 0.5) / s - 0.5).ravel()\n"
            "    def share(x0, y0=0.2):\n"
            "        img = C.disk_profile(grid[None, :] - x0, grid[:, None] - y0, radius, edge)\n"
            "        return img.reshape(centres.size, s, centres.size, s).mean(axis=(1, 3))\n"
            "    norm = share(0.3).sum()\n"
            "    mu = n_e * share(0.3) / norm + b_e\n"
            "    dmu = n_e * (share(0.3 + 1e-3) - share(0.3 - 1e-3)) / (2e-3 * norm)\n"
            "    return 1.0 / np.sqrt(np.sum(dmu ** 2 / mu ** 2))",
    # cos of alpha in degrees
    "03.1": "def angles_from_centroid(x, y):\n"
            "    a = np.degrees(np.arctan((np.asarray(x) - X_CF) * P / F))\n"
            "    b = np.degrees(np.arctan((np.asarray(y) - Y_CF) * P * np.cos(a) / F))\n"
            "    return a, b",
    # a wrong sign
    "03.2": "def ideal_alpha_error(alpha_deg, delta_f_mm):\n"
            "    a = np.radians(alpha_deg)\n"
            "    return -np.degrees(delta_f_mm / F * np.sin(a) * np.cos(a))",
    # an off-by-one total degree: k in 0..n-1
    "04.1": "def validation_errors(train, val, n):\n"
            "    xm, ym = train.x.mean('shot').values, train.y.mean('shot').values\n"
            "    def scaled(v, ref):\n"
            "        return 2 * (v - ref.min()) / (ref.max() - ref.min()) - 1\n"
            "    def design(x, y):\n"
            "        u, v = scaled(x, xm), scaled(y, ym)\n"
            "        return np.stack([u ** (k - l) * v ** l for k in range(n)\n"
            "                         for l in range(k + 1)], -1)\n"
            "    tr, va = [], []\n"
            "    for angle in ('alpha', 'beta'):\n"
            "        coef, *_ = np.linalg.lstsq(design(xm, ym), train[angle].values, rcond=None)\n"
            "        tr.append(np.abs(design(xm, ym) @ coef - train[angle].values).mean())\n"
            "        est = design(val.x.values, val.y.values) @ coef\n"
            "        va.append(np.abs(est - val[angle].values[:, None]).mean())\n"
            "    return sum(tr), sum(va)\n"
            "errs = {n: validation_errors(train, val, n) for n in range(1, 9)}\n"
            "chosen = min(errs, key=lambda n: errs[n][1])",
    # the population standard deviation (ddof=0)
    "04.2": "def global_statistics(err):\n"
            "    out = {}\n"
            "    for angle in ('alpha', 'beta'):\n"
            "        local_err, max_err = err[angle].mean('shot'), err[angle].max('shot')\n"
            "        out[(angle, 'mu')] = float(local_err.mean())\n"
            "        out[(angle, 'sigma')] = float(local_err.std())\n"
            "        out[(angle, 'M')] = float(max_err.mean())\n"
            "        out[(angle, 'sigma_M')] = float(max_err.std())\n"
            "    return out",
    # half the rectangle: 3 sigma_M wide instead of 6
    "05.1": "def rectangle_areas(table):\n"
            "    return {m: 3 * table[m][('alpha', 'sigma_M')]\n"
            "            * 3 * table[m][('beta', 'sigma_M')] for m in table.columns}",
    # eq. (5) taken at its word: the common part averaged out too
    "06.1": "def averaging_gain(common, specific, n):\n"
            "    return n ** 0.5",
    # the mounting angle added outside the tangent
    "07.1": "def fit_x_model(alpha_read, x, pitch):\n"
            "    def along_x(alpha, x_cf, f_mm, alpha0):\n"
            "        return x_cf + f_mm / pitch * np.tan(np.radians(alpha)) + alpha0\n"
            "    params, _ = curve_fit(along_x, alpha_read, x, p0=(float(np.mean(x)), 5.0, 0.0))\n"
            "    return tuple(float(v) for v in params)",
    # the frames imported without their dark and flat
    "08.1": "def centroids_of(folder, dark, flat):\n"
            "    return centroid.locate(io.open_frames(folder), 'projection', progress=False)",
    # a first-order polynomial: the geometry over +-6 deg is not linear
    "08.2": "def calibrate_and_export(train, out):\n"
            "    cal = calibration.fit(train, 'polynomial', order=1)\n"
            "    export.export(cal, out, format='c')\n"
            "    return cal",
    # the standard deviation of X instead of |X| (the mean is |X|'s)
    "09.1": "def abs_ratio_uniform(c, w):\n"
            "    c = abs(c)\n"
            "    mean = c if c >= w else (c ** 2 + w ** 2) / (2 * w)\n"
            "    return (w ** 2 / 3) ** 0.5 / mean",
    # a wrong sign: up minus down
    "09.2": "def backlash_from_errors(e, d):\n"
            "    e, d = np.asarray(e, dtype=float), np.asarray(d)\n"
            "    return 0.5 * (np.nanmean(e[d > 0]) - np.nanmean(e[d < 0]))",
}
