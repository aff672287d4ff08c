"""Rendering a neural scene into predicted matched-filter images, registered in ``RENDERERS``.

The coherent renderer: predicted matched-filter images of the neural surface, through the
simulator's own physics.

Each step, for each chosen view v:

    samples p* of f_theta = 0 (``recon/surface.py``), normals n, areas dA
    c_v = scatter(p*, n, dA, Gamma_phi, Tx_v, Rx_v)        (``radar/scattering.py``)
    y_v = A_v c_v                                          (``radar/operator.py``)
    I_v(x) = A_v(x)^H y_v / ||A_v(x)||^2                   at the data voxels x

so the prediction carries the carrier phase of every sample, the interference between them,
the array's exact, shift-variant PSF and its sidelobes, and the same column normalisation
as the observed image. Gradients reach theta through the sample positions (the phase of A
and the geometry of the lobe) and their areas (which grow with the surface's curvature as it
moves out) and their normals (which turn the lobe, ``surface.project_to_surface``), and phi
through the reflection of each sample. With a material head (``field.materials``) that is the
simulator's own Fresnel coefficient of the sample's material at its incidence angle in that
view, in expectation over the head's class probabilities (``materials.mixture_fresnel``,
tabulated in the cosine: ``materials.FresnelTable``), so the data supervise what each
surface is made of; without one, a free reflectivity
Gamma_phi >= 0 stands in for it (kept as an option for comparison). Facing and shadows are frozen
between refreshes: shadows are traced against the network evaluated on the image grid
(trilinear), a cheap stand-in for it.

Why not a shell c = Gamma delta_sigma(f) dV on voxels (the textbook GeRaF rendering, and this
project's earlier incoherent renderers): summed coherently across a flat surface it returns
exp(-2 k^2 sigma^2) of a sheet's amplitude (the Gaussian's Fourier transform at the
round-trip wavenumber 2k), e^-197 at 79 GHz and sigma = 6 mm; summed incoherently it cannot
say where a smooth surface glints, and started at the true surface that fit drifted from
1.2 to 9.1 mm Chamfer. Coherent prediction from points on the surface tolerates *smooth*
geometric error well (``benchmarks/coherent_model.py``: a 2 mm dilation of the true scene
still correlates 0.92 with the data, white per-sample jitter of lambda/4 only 0.69).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import torch

from ..geometry import Grid, interpolated_sdf
from ..materials import FresnelTable, class_permittivities
from ..progress import progress_bar
from ..radar import SPEED_OF_LIGHT, Measurements, SensingOperator
from ..radar.facets import facet_phase_weights
from ..radar.imaging import require_image_memory
from ..radar.scattering import DIFFUSE_WEIGHT, SPECULAR_EXPONENT, lit_mask, po_spectrum, scatter
from ..radar.surface_plan import SURFACES
from ..radar.transmission import Slabs, band_factor, through_objects
from ..registry import Registry
from ..scene import Scene
from .surface import SurfaceCandidates, project_to_surface, surface_candidates
from .surface_mesh import SurfaceMesh, mesh_facets, surface_mesh

__all__ = ["RENDERERS", "CoherentRenderer"]

RENDERERS: Registry = Registry("renderer")


@RENDERERS.register("coherent")
class CoherentRenderer:
    """Predicted and observed per-view complex MF images of a RadarField at voxels of ``grid``.

    measurements : the data. grid : the image grid (data voxels are its voxel centres).
    element_step : image with every n-th Tx and Rx only (both the data and the prediction,
    so they stay comparable): the same aperture and resolution, n^2 times fewer pairs (of a
    scan, 1/n^2 of its frames). frequency_step : every n-th frequency, alike (ValueError
    when the unambiguous range c / (2 n df) is shorter than the grid's range extent). A
    view is a frame, or all frames of a scan (``Acquisition.scans``), whose samples scatter
    towards each frame's own phase centres (their facets' phase integral, facing and shadows
    from the scan's).
    surface : "facets", flat triangles of f = 0 whose phase is integrated across them
    (``recon/surface_mesh.py``: the converged quadrature, as the simulator's), or "points",
    random points near it (``recon/surface.py``: a Monte Carlo quadrature, kept for comparison).
    spacing_m : the facets' marching-cubes cell, or the points' spacing (lambda/3 by default). shadows : trace them.
    dtype : float32, or float64 for gradient checks. smoothing_m : radius of the local mean
    taken of the surface velocity the loss asks for (``surface.smoothed_velocity``).
    bands : also image each of this many equal sub-bands of the frequencies on its own
    (``band_observed``, and ``__call__(bands=True)``), for a loss that compares sub-band
    images (``recon/losses.py``, "split"); 1: the full band only.
    through : a known scene the fitted surface is seen through (a box the objects stand in,
    whose own return the caller took out of the data): each surface sample's return is
    weighted by its two-way line of sight through that scene's objects from each view's
    phase centre (T^2 of the slabs crossed at every frequency, their excess path's delay
    and resonances; :func:`~rfsdf.radar.transmission.through_objects`), found at each refresh
    like the shadows; None: nothing in the way but the fitted surface itself.
    """

    def __init__(self, measurements: Measurements, grid: Grid, *, element_step: int = 1, frequency_step: int = 1,
                 surface: str = "facets", spacing_m: float | None = None,
                 specular_exponent: float = SPECULAR_EXPONENT, diffuse_weight: float = DIFFUSE_WEIGHT,
                 shadows: bool = True, device="cpu", dtype: torch.dtype = torch.float32, smoothing_m: float = 0.0,
                 bands: int = 1, through: Scene | None = None, progress: bool = False):
        if surface not in SURFACES:
            raise ValueError(f"unknown surface {surface!r}; known: {', '.join(SURFACES)}")
        self.surface = surface
        self.grid, self.device = grid, torch.device(device)
        data = measurements.thinned(element_step).every_frequency(frequency_step)
        if frequency_step > 1:
            _require_unambiguous(data.acquisition, grid, frequency_step)
        acq = data.acquisition
        self.voxel_m = float(np.max(grid.voxel_m))
        self.spacing_m = spacing_m or acq.wavelength_m / 3
        self.lobe = {"specular_exponent": specular_exponent, "diffuse_weight": diffuse_weight}
        self.shadows = shadows
        self.smoothing_m = smoothing_m
        # a view: a frame, or a scan's frames together (Acquisition.scans)
        self.operators = [SensingOperator(acq.coherent_view(v)) for v in range(acq.num_views)]
        self.frames = [acq.frames(v) for v in range(acq.num_views)]
        tx_centres, rx_centres = acq.view_centres()
        self.tx_centres = tx_centres.to(self.device, dtype)  # (V, 3)
        self.rx_centres = rx_centres.to(self.device, dtype)
        # per view, each frame's Tx and Rx phase centres, (F, 3) each (a MIMO view: one frame)
        self.frame_centres = [(op.acq.tx_m.mean(1).to(self.device, dtype), op.acq.rx_m.mean(1).to(self.device, dtype))
                              for op in self.operators]
        require_image_memory(acq.num_views, grid, "the fit's images")
        self.voxels = grid.points(device=self.device, dtype=dtype)  # (N, 3)
        self.column_norms_sq = torch.stack([op.column_norms_sq(self.voxels) for op in self.operators])  # (V, N)
        k = acq.shape[3]
        if not 1 <= bands <= k:
            raise ValueError(f"bands must be 1 to the {k} frequencies, got {bands}")
        # (B, K): sub-band b holds frequencies [b K / B, (b + 1) K / B) (sorted as the data's axis)
        order = torch.argsort(acq.frequencies_hz)
        self.band_masks = torch.zeros(bands, k, dtype=torch.bool)
        for b, part in enumerate(order.tensor_split(bands)):
            self.band_masks[b, part] = True
        self.band_masks = self.band_masks.to(self.device)
        self.band_shares = self.band_masks.sum(1).to(dtype) / k  # (B,) K_b / K
        self.data = data  # the thinned data the images are formed from
        views = progress_bar(range(len(self.operators)), desc="observed images", enabled=progress)
        if bands > 1:
            # one adjoint per band: the full band's image is their sum
            band_observed = torch.stack([self._band_images(v, self.view_data(v), self.voxels, self.column_norms_sq[v])
                                         for v in views])  # (V, B, N)
            observed = self.full_band(band_observed)
        else:
            observed = torch.stack([self._normalise(self.operators[v].adjoint(self.view_data(v), self.voxels),
                                                    self.column_norms_sq[v]) for v in views])
        self.observed_peak = float(observed.abs().max())  # the data's units per unit of self.observed
        self.observed = observed / self.observed_peak  # (V, N) complex, peak amplitude 1
        # (V, B, N) complex, in the units of self.observed; None for the full band only
        self.band_observed = band_observed / self.observed_peak if bands > 1 else None
        self.centre_frequency_hz = acq.center_frequency_hz
        self.wavenumber_rad_m = acq.wavenumber_rad_m
        self.po_spectrum = po_spectrum(acq.frequencies_hz).to(self.device)  # (K,), the data's last axis
        self.frequencies_hz = acq.frequencies_hz.double().to(self.device)  # (K,)
        self.wavenumbers_rad_m = (2 * np.pi / SPEED_OF_LIGHT) * self.frequencies_hz  # (K,)
        self.through = through
        self.candidates: SurfaceCandidates | SurfaceMesh | None = None
        self.lit: torch.Tensor | None = None  # (V, Q) bool
        # (V, Q) complex128 and (V, Q, C): each candidate's two-way line of sight through
        # ``through`` at the centre frequency and the slabs it crosses, per view, and (V, K, Q)
        # complex64 their T at each frequency over the centre's (None without one)
        self.sight: torch.Tensor | None = None
        self.slabs: Slabs | None = None
        self.through_spectrum: torch.Tensor | None = None
        self._features: torch.Tensor | None = None  # the geometry features at the candidates, while f is held
        self._fresnel: dict[tuple[str, ...], FresnelTable] = {}  # a material head's classes -> their table

    @property
    def num_views(self) -> int:
        return len(self.operators)

    def view_data(self, view: int) -> torch.Tensor:
        """(F, T, R, K) complex: the (thinned) data of view ``view``, on the renderer's device."""
        return self.data.data[self.frames[view]].to(self.device)

    @staticmethod
    def _normalise(back_projection: torch.Tensor, norms: torch.Tensor) -> torch.Tensor:
        """A^H y / ||A_q||^2 given the column norms (X,), and 0 where no antenna sees the target."""
        seen = norms > 0
        return torch.where(seen, back_projection / torch.where(seen, norms, 1.0), 0.0)

    def _band_images(self, view: int, y: torch.Tensor, targets: torch.Tensor, norms: torch.Tensor) -> torch.Tensor:
        """(B, X) the normalised MF image of data ``y`` (F, T, R, K) from each sub-band's
        frequencies alone at ``targets`` (X, 3) of column norms ``norms`` (X,): A_b^H y_b /
        ||A_b,q||^2, where ||A_b,q||^2 is the band's share K_b / K of the column norm (every
        phasor has modulus 1)."""
        images = self.operators[view].adjoint(y, targets, bands=self.band_masks.to(y.device))  # (B, X)
        return self._normalise(images, norms) / self.band_shares[:, None].to(images.device)

    def observed_at(self, view: int, targets: torch.Tensor) -> torch.Tensor:
        """(X,) complex: the data's full-band image of view ``view`` at any points ``targets``
        (X, 3) [m], normalised as ``observed`` (e.g. along a line of sight, between voxels)."""
        norms = self.operators[view].column_norms_sq(targets)
        return self._normalise(self.operators[view].adjoint(self.view_data(view), targets), norms) / self.observed_peak

    def full_band(self, band_images: torch.Tensor) -> torch.Tensor:
        """(..., X) the full band's image from its sub-bands' (..., B, X): their sum weighted
        by each band's share K_b / K of the frequencies (the adjoint is linear in the data)."""
        return torch.einsum("...bx,b->...x", band_images, self.band_shares.to(band_images.dtype))

    @torch.no_grad()
    def refresh(self, sdf, generator: torch.Generator) -> None:
        """New surface candidates of ``sdf`` ((N, 3) -> (N,) [m]) and their facing/shadow masks
        in every view, held fixed (no gradient) until the next refresh; f at the grid's voxel
        centres says where the surface can be, and ``generator`` draws a "points" surface's points."""
        values = torch.cat([sdf(chunk).to(self.voxels.dtype) for chunk in self.voxels.split(1 << 16)])
        if self.surface == "facets":
            self.candidates = surface_mesh(sdf, self.voxels, values, self.voxel_m, self.spacing_m)
        else:
            self.candidates = surface_candidates(sdf, self.voxels, values, self.voxel_m, self.spacing_m, generator)
        self._features = None
        occluder = interpolated_sdf(values, self.grid) if self.shadows else None
        anchors, normals = self.candidates.anchors, self.candidates.normals
        self.lit = torch.stack([
            lit_mask(anchors, normals, self.tx_centres[v], self.rx_centres[v], occluder=occluder,
                     shadow_offset_m=self.voxel_m)
            for v in range(self.num_views)
        ])
        if self.through is not None:
            centres = 0.5 * (self.tx_centres + self.rx_centres)
            sights, slabs = zip(*(through_objects(self.through, anchors, normals, centre, self.centre_frequency_hz)
                                  for centre in centres))
            self.sight, self.slabs = torch.stack(sights), Slabs.stack(list(slabs))
            self.lit = self.lit & (self.sight != 0)
            self.through_spectrum = self._through_spectrum()

    def surface_state(self) -> dict | None:
        """The surface as a checkpoint keeps it (tensors and numbers), with its masks; None
        before the first refresh."""
        cand = self.candidates
        if cand is None:
            return None
        kept = cand.state() if isinstance(cand, SurfaceMesh) else dataclasses.asdict(cand)
        return {"kind": self.surface, **kept, "lit": self.lit, "sight": self.sight,
                "slabs": None if self.slabs is None else self.slabs.state()}

    def load_surface_state(self, state: dict | None) -> None:
        """The surface and masks :meth:`surface_state` kept (None: none yet)."""
        if state is None:
            return
        state = dict(state)
        kind, self.lit = state.pop("kind"), state.pop("lit")
        self.sight, slabs = state.pop("sight", None), state.pop("slabs", None)
        self.slabs = None if slabs is None else Slabs(**slabs)
        self.through_spectrum = None if slabs is None else self._through_spectrum()
        if kind != self.surface:
            raise ValueError(f"the checkpoint's surface is {kind}, this renderer's {self.surface}")
        self.candidates = SurfaceMesh.from_state(state) if kind == "facets" else SurfaceCandidates(**state)
        self._features = None

    def _through_spectrum(self) -> torch.Tensor:
        """(V, K, Q) complex64: each view's lit candidates' slabs' T at the data's frequencies
        over the centre frequency's (:func:`~rfsdf.radar.transmission.band_factor`; 0 where
        unlit), found once per refresh."""
        spectrum = torch.zeros((self.num_views, len(self.frequencies_hz), self.lit.shape[1]), dtype=torch.complex64,
                               device=self.device)
        for v in range(self.num_views):
            idx = self.lit[v].nonzero().squeeze(1)
            spectrum[v][:, idx] = band_factor(self.through, self.slabs[v, idx], self.frequencies_hz,
                                              self.centre_frequency_hz).to(spectrum.dtype)
        return spectrum

    def predict_data(self, view: int, points: torch.Tensor, normals: torch.Tensor, area_m2: torch.Tensor,
                     reflection, corners_m: torch.Tensor | None = None, sight: torch.Tensor | None = None,
                     through_spectrum: torch.Tensor | None = None) -> torch.Tensor:
        """y_v = A_v c_v (F, T, R, K) of surface samples (Q, 3) [m] lit in view ``view``, with
        c_v (F, Q) from :func:`~rfsdf.radar.scattering.scatter` (``reflection`` as there) in each
        of its frames, and for
        facets (their ``corners_m`` (Q, 3, 3) [m] relative to the centroids ``points``) times
        the phase integral across each at each frequency; seen through objects, times each
        sample's ``sight`` (Q,) and its ``through_spectrum`` (K, Q) (``through``: its slabs'
        T over the band). The
        simulator's data, for the simulator's samples and their Fresnel reflection."""
        tx, rx = self.tx_centres[view], self.rx_centres[view]
        # each frame's lobe towards its own phase centres, as the simulator's (a scan's frames
        # see a facet from up to some 15 degrees apart; its centre's lobe alone left the true
        # scene 12-19 % dimmer than sar-77g's data, benchmarks/scan_model.py)
        c = torch.stack([scatter(points, normals, area_m2, reflection, frame_tx, frame_rx, self.wavenumber_rad_m,
                                 **self.lobe) for frame_tx, frame_rx in zip(*self.frame_centres[view])])  # (F, Q)
        if sight is not None:
            c = c * sight.to(c.dtype)
        spectrum = None  # (K, Q): what each frequency adds, alike in every frame (from the view's centre)
        if corners_m is not None:
            spectrum = facet_phase_weights(points, corners_m, tx, rx, self.wavenumbers_rad_m).to(c.dtype)
        if through_spectrum is not None:
            band = through_spectrum.to(c.dtype)
            spectrum = band if spectrum is None else spectrum * band
        return self.operators[view].forward(points, c, spectrum=spectrum) * self.po_spectrum.to(c.dtype)

    def class_permittivities(self, materials: tuple[str, ...]) -> torch.Tensor:
        """(K,) complex128 relative permittivities of catalogue materials at the data's centre
        frequency (inf for metal): the classes of a material head."""
        return class_permittivities(materials, self.centre_frequency_hz).to(self.device)

    def fresnel_table(self, materials: tuple[str, ...]) -> FresnelTable:
        """The classes' Fresnel coefficients tabulated in the cosine (built once per classes)."""
        if materials not in self._fresnel:
            eps = class_permittivities(materials, self.centre_frequency_hz)
            self._fresnel[materials] = FresnelTable(eps).to(self.device)
        return self._fresnel[materials]

    def surface_materials(self, field, *, geometry: bool = True) -> torch.Tensor | None:
        """(Q, K) class probabilities at the current surface candidates, or None for a field
        with a free reflectivity. ``geometry=False``: f held since the last refresh, so the
        geometry features there are computed once per refresh and only the head is
        differentiated (a step then costs what it cost with a free reflectivity)."""
        if getattr(field, "material_head", None) is None:
            return None
        if geometry:
            return field.material(self.candidates.anchors)
        if self._features is None:
            with torch.no_grad():
                self._features = field.material_features(self.candidates.anchors)
        return field.material_head(self._features)

    def surface_geometry(self, field, *, geometry: bool = True):
        """The surface as the renderer sums it: points (Q, 3) [m] (the facets' centroids),
        unit normals (Q, 3), areas (Q,) [m^2] and the facets' corners (Q, 3, 3) [m] relative to
        them (None for points); on f as it is (differentiable when gradients are recorded), or,
        ``geometry=False``, as it was at the last refresh."""
        cand = self.candidates
        if self.surface == "facets":
            facets = mesh_facets(field.sdf, cand, smoothing_m=self.smoothing_m) if geometry else cand.facets
            return facets.centroids, facets.normals, facets.area_m2, facets.corners_m
        if geometry:
            return (*project_to_surface(field.sdf, cand, smoothing_m=self.smoothing_m), None)
        return (*cand.projected(), None)

    def __call__(self, field, views: torch.Tensor, voxel_index: torch.Tensor, *, geometry: bool = True,
                 probabilities: torch.Tensor | None = None, bands: bool = False,
                 lines: list[torch.Tensor] | None = None, only: torch.Tensor | None = None):
        """(len(views), X) complex predicted c_hat_v at the voxels ``voxel_index`` (X,);
        ``geometry=False``: f as it was at the last refresh (the caller holds it fixed since),
        differentiable in the reflection only, and f is not evaluated at all. ``probabilities``:
        :meth:`surface_materials`, when the caller has them already. ``bands``: each sub-band's
        image instead, (len(views), B, X), as ``band_observed``. ``lines``: also each view's
        full-band image at points of its own (one (L_v, 3) tensor [m] per view, as
        :meth:`observed_at`), from the same prediction: then (images, [(L_v,) complex]).
        ``only`` (Q,) bool: these candidates alone, as if the others reflected nothing."""
        if self.candidates is None:
            raise RuntimeError("call refresh() before rendering")
        surface = self.surface_geometry(field, geometry=geometry)
        reflection = self._reflection(field, probabilities)
        voxels, complex_dtype = self.voxels[voxel_index], torch.promote_types(surface[0].dtype, torch.complex64)
        images, line_images = [], []
        for i, v in enumerate(views.tolist()):
            extra = None if lines is None else lines[i]  # (L, 3) or None
            targets = voxels if extra is None else torch.cat([voxels, extra])
            norms = self.column_norms_sq[v, voxel_index]
            if extra is not None:
                norms = torch.cat([norms, self.operators[v].column_norms_sq(extra)])
            idx = (self.lit[v] if only is None else self.lit[v] & only).nonzero().squeeze(1)
            if len(idx) == 0:
                image = torch.zeros((len(self.band_masks), len(targets)) if bands else (len(targets),),
                                    dtype=complex_dtype, device=self.device)
            else:
                y = self._predict_lit(v, idx, surface, reflection)
                image = (self._band_images(v, y, targets, norms) if bands
                         else self._normalise(self.operators[v].adjoint(y, targets), norms))
            images.append(image[..., :len(voxels)])
            if extra is None:
                line_images.append(None)
            else:
                line_images.append(self.full_band(image[..., len(voxels):]) if bands else image[len(voxels):])
        return torch.stack(images) if lines is None else (torch.stack(images), line_images)

    @torch.no_grad()
    def segment_images(self, field, views: torch.Tensor, voxel_index: torch.Tensor,
                       segments: torch.Tensor) -> torch.Tensor:
        """(S, len(views), X) complex: the full-band image at the voxels ``voxel_index`` (X,) of
        each segment of the surface alone (``segments`` (S, Q) bool over the candidates, each as
        ``only``), f as at the last refresh: one adjoint of the segments' stacked data per view,
        so S images cost about one render's phasors and S of its products."""
        surface = self.surface_geometry(field, geometry=False)
        reflection = self._reflection(field, self.surface_materials(field, geometry=False))
        voxels, complex_dtype = self.voxels[voxel_index], torch.promote_types(surface[0].dtype, torch.complex64)
        images = []
        for v in views.tolist():
            data = []
            for mine in segments:
                idx = (self.lit[v] & mine).nonzero().squeeze(1)
                data.append(self._predict_lit(v, idx, surface, reflection) if len(idx) else
                            torch.zeros(self.operators[v].acq.shape, dtype=complex_dtype, device=self.device))
            image = self.operators[v].adjoint(torch.stack(data), voxels)  # (S, X): data (S, 1, T, R, K)
            images.append(self._normalise(image, self.column_norms_sq[v, voxel_index]))
        return torch.stack(images, dim=1)

    def _reflection(self, field, probabilities: torch.Tensor | None):
        """idx (Q_v,) -> (cos(theta_inc) -> Gamma) of the candidates ``idx``: ``field``'s free
        reflectivity, or the Fresnel coefficient expected from its class ``probabilities``
        (None: :meth:`surface_materials`, with f as it is)."""
        if probabilities is None:
            probabilities = self.surface_materials(field)
        if probabilities is None:
            amplitude = field.reflectivity(self.candidates.anchors)
            return lambda idx: lambda _cos: amplitude[idx]
        table = self.fresnel_table(tuple(field.materials))
        return lambda idx: lambda cos: table.mixture(cos, probabilities[idx])

    def _predict_lit(self, view: int, idx: torch.Tensor, surface, reflection) -> torch.Tensor:
        """:meth:`predict_data` of the candidates ``idx`` (lit in ``view``) of ``surface`` (as
        :meth:`surface_geometry` gives it) with ``reflection`` (as :meth:`_reflection` gives it),
        seen through the ``through`` scene where there is one."""
        points, normals, area, corners = surface
        through = {} if self.sight is None else {
            "sight": self.sight[view, idx],
            "through_spectrum": None if self.through_spectrum is None else self.through_spectrum[view][:, idx]}
        return self.predict_data(view, points[idx], normals[idx], area[idx], reflection(idx),
                                 None if corners is None else corners[idx], **through)


def _require_unambiguous(acquisition, grid: Grid, frequency_step: int) -> None:
    """ValueError when the frequencies' unambiguous path length c / df is shorter than the
    spread of the round-trip paths from some view's phase centre to the grid's corners."""
    f = acquisition.frequencies_hz
    if len(f) < 2:
        return
    unambiguous = SPEED_OF_LIGHT / float(torch.diff(torch.sort(f).values).max())  # path length [m]
    corners = torch.tensor(np.array(np.meshgrid(*zip(grid.lower_m, grid.upper_m), indexing="ij")).reshape(3, -1).T)
    tx, rx = acquisition.view_centres()
    paths = (corners[None] - tx[:, None]).norm(dim=2) + (corners[None] - rx[:, None]).norm(dim=2)  # (V, 8)
    spread = float((paths.max(1).values - paths.min(1).values).max())
    if unambiguous < spread:
        raise ValueError(f"frequency_step {frequency_step}: the unambiguous path length {unambiguous:.3g} m is shorter "
                         f"than the grid's {spread:.3g} m of round-trip paths; a smaller frequency_step")
