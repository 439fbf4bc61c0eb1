"""The camera effects, each rendered and measured: noise that grows with gain in the dark,
auto-exposure and white balance that lag a change of light by their time constants, vignetting,
lens blur, chromatic fringes, JPEG blocks, motion blur from speed and turn rate, rolling shutter,
and ceiling-light highlights that move with the robot. Seeded; time is each frame's `now`."""

from __future__ import annotations

import math
from typing import Any

import cv2
import numpy as np
import pytest

from lanewarden.actuation.base import Pose2D
from lanewarden.scenarios.camera import CameraModel
from lanewarden.scenarios.camera_effects import CameraEffects, light_at
from lanewarden.scenarios.highlights import Highlights
from lanewarden.scenarios.render import CameraRenderer
from lanewarden.scenarios.spec import CameraSpec, CeilingLightsSpec, LightingSpec
from lanewarden.scenarios.texture import GroundTexture

RES = 0.004  # m per texture pixel
CAMERA = CameraModel(width_px=320, height_px=240)
#: A camera with only the effect under test (no vignetting, blur, fringes or rolling shutter).
BARE: dict[str, Any] = {"optics": {"vignetting": 0.0, "blur_mrad": 0.0, "chromatic": 0.0},
                        "rolling_shutter_s": 0.0, "motion_blur": False}


def camera_spec(**changes: Any) -> CameraSpec:
    data: dict[str, Any] = {**BARE}
    for key, value in changes.items():
        data[key] = {**data[key], **value} if isinstance(value, dict) and key in data else value
    return CameraSpec.model_validate(data)


def flat_texture(level: int = 128, color: tuple[int, int, int] | None = None,
                 gloss: int | None = None, res: float = RES,
                 size_m: float = 8.0) -> GroundTexture:
    """A uniform floor `size_m` square from (-size_m / 4, -size_m / 2)."""
    size = int(size_m / res)
    gray = np.full((size, size), level, np.uint8)
    bgr = None if color is None else np.full((size, size, 3), color, np.uint8)
    fill = color or (level, level, level)
    return GroundTexture(gray=gray, bgr=bgr, m_per_px=res, x_min=-size_m / 4, y_max=size_m / 2,
                         fill_gray=level, fill_bgr=fill,
                         gloss=None if gloss is None else np.full((size, size), gloss, np.uint8))


def step_texture(y_edge_m: float, res: float = RES, size_m: float = 8.0) -> GroundTexture:
    """Dark (40) floor, light (220) left of `y_edge_m`."""
    texture = flat_texture(40, res=res, size_m=size_m)
    rows = texture.y_max - (np.arange(texture.gray.shape[0]) + 0.5) * res
    texture.gray[rows > y_edge_m, :] = 220
    return texture


ORIGIN = Pose2D()


def render(renderer: CameraRenderer, now: float | None, pose: Pose2D = ORIGIN,
           velocity: tuple[float, float] = (0.0, 0.0), noise: bool = True,
           color: bool = False) -> np.ndarray:
    w, h = renderer.size
    if color:
        return renderer.render_bgr(pose, np.empty((h, w, 3), np.uint8), velocity,
                                   renderer.next_noise_index() if noise else None, now).copy()
    return renderer.render_gray(pose, np.empty((h, w), np.uint8), velocity,
                                renderer.next_noise_index() if noise else None, now).copy()


def renderer_for(spec: CameraSpec, texture: GroundTexture, lighting: LightingSpec | None = None,
                 camera: CameraModel = CAMERA, seed: int = 0,
                 highlights: Highlights | None = None) -> CameraRenderer:
    channels = 1 if texture.bgr is None else 3
    effects = CameraEffects(spec, lighting or LightingSpec(ceiling=None), camera,
                            channels=channels, seed=seed)
    return CameraRenderer(texture, camera, seed=seed, effects=effects, highlights=highlights)


def floor_rows(camera: CameraModel) -> slice:
    """Image rows that see the floor (below the horizon) in every column."""
    gx, _ = camera.pixel_ground_points()
    first = int(np.nonzero(np.isfinite(gx).all(axis=1))[0][0])
    return slice(first + 2, camera.height_px)


def noise_std(renderer: CameraRenderer, now: float) -> tuple[float, float, float]:
    """(mean level, noise std, gain) of a flat floor: two frames' difference / sqrt 2."""
    a = render(renderer, now).astype(float)
    b = render(renderer, now + 1 / 30).astype(float)
    rows = floor_rows(renderer.camera)
    effects = renderer.effects
    assert effects is not None
    gain = effects.settle(a.astype(np.uint8), None).gain
    return float(a[rows].mean()), float(np.std(a[rows] - b[rows]) / math.sqrt(2)), gain


def test_noise_grows_with_the_gain_the_dark_asks_for() -> None:
    spec = camera_spec()
    bright = renderer_for(spec, flat_texture(128), LightingSpec(brightness=1.0, ceiling=None))
    dark = renderer_for(spec, flat_texture(128), LightingSpec(brightness=0.05, ceiling=None))
    level_b, sigma_b, gain_b = noise_std(bright, 0.0)
    level_d, sigma_d, gain_d = noise_std(dark, 0.0)
    # Both exposed to the target (half of full scale): the dark one by a 30 ms shutter (the
    # longest) and gain 6.7.
    assert level_b == pytest.approx(127.5, abs=2.0) and level_d == pytest.approx(127.5, abs=2.0)
    assert gain_b == pytest.approx(1.0) and gain_d == pytest.approx(6.67, abs=0.05)
    # shot + read noise: sqrt(level * 255 g / 6000 + (3 * 255 g / 6000)^2) grey levels
    assert sigma_b == pytest.approx(2.34, abs=0.25)
    assert sigma_d == pytest.approx(6.08, abs=0.5)


def test_noise_is_seeded() -> None:
    a = renderer_for(camera_spec(), flat_texture(), seed=3)
    b = renderer_for(camera_spec(), flat_texture(), seed=3)
    c = renderer_for(camera_spec(), flat_texture(), seed=4)
    first = render(a, 0.0)
    assert np.array_equal(first, render(b, 0.0))
    assert not np.array_equal(first, render(c, 0.0))


def mean_levels(renderer: CameraRenderer, until_s: float, color: bool = False) -> np.ndarray:
    times = np.arange(0.0, until_s, 1 / 30)
    rows = floor_rows(renderer.camera)
    if color:
        return np.array([render(renderer, t, noise=False, color=True)[rows].reshape(-1, 3)
                         .mean(axis=0) for t in times])
    return np.array([render(renderer, t, noise=False)[rows].mean() for t in times])


def crossing_time(values: np.ndarray, level: float, after_s: float) -> float:
    times = np.arange(len(values)) / 30
    later = np.nonzero((times > after_s) & (values >= level))[0]
    return float(times[later[0]])


@pytest.mark.parametrize("tau", [0.4, 1.0])
def test_auto_exposure_lags_a_light_switched_down_by_its_time_constant(tau: float) -> None:
    lighting = LightingSpec(ceiling=None, changes=[{"at_s": 1.01, "brightness": 0.25}])
    renderer = renderer_for(camera_spec(exposure={"time_constant_s": tau}), flat_texture(128),
                            lighting)
    levels = mean_levels(renderer, 1.0 + 3 * tau)
    assert levels[30] == pytest.approx(127.5, abs=1.5)  # settled before the change
    assert levels[31] == pytest.approx(127.5 / 4, abs=1.5)  # the first frame after: a quarter
    # It recovers as 1 - exp(-t / tau) in log exposure: 63 % of the way (a factor 4^0.632 of
    # the dark level) after tau, plus the frame its metering takes.
    assert crossing_time(levels, 127.5 / 4 * 4 ** 0.632, 1.0) == pytest.approx(
        1.01 + tau + 1 / 30, abs=0.05)
    assert levels[-1] == pytest.approx(127.5 * 4 ** -math.exp(-3), abs=3)


def test_fixed_exposure_does_not_follow_the_light() -> None:
    lighting = LightingSpec(ceiling=None, changes=[{"at_s": 0.5, "brightness": 0.5}])
    renderer = renderer_for(camera_spec(exposure={"auto": False, "exposure_s": 0.01}),
                            flat_texture(128), lighting)
    levels = mean_levels(renderer, 2.0)
    assert levels[5] == pytest.approx(128, abs=1) and levels[-1] == pytest.approx(64, abs=1)


def test_white_balance_lags_a_change_of_light_colour() -> None:
    lighting = LightingSpec(ceiling=None, changes=[{"at_s": 1.01, "color": "#ffc080"}])
    renderer = renderer_for(camera_spec(white_balance={"time_constant_s": 0.8}),
                            flat_texture(128, color=(128, 128, 128)), lighting)
    bgr = mean_levels(renderer, 4.0, color=True)
    log_ratio = np.log(bgr[:, 2] / bgr[:, 0])  # red over blue
    assert log_ratio[30] == pytest.approx(0.0, abs=0.02)  # grey under white light
    assert log_ratio[31] == pytest.approx(math.log(255 / 128), abs=0.03)  # warm light: red
    # back towards grey with the white balance's time constant: 63 % of the way after 0.8 s
    crossed = crossing_time(-log_ratio, -math.log(255 / 128) * (1 - 0.632), 1.0)
    assert crossed == pytest.approx(1.01 + 0.8 + 1 / 30, abs=0.05)


def test_vignetting_darkens_the_corners_by_its_fraction() -> None:
    camera = CameraModel(width_px=320, height_px=240, pitch_down_deg=80.0)  # floor everywhere
    renderer = renderer_for(camera_spec(optics={"vignetting": 0.4},
                                        exposure={"auto": False}), flat_texture(150),
                            camera=camera)
    image = render(renderer, 0.0, noise=False).astype(float)
    assert image[120, 160] == pytest.approx(150, abs=1)
    assert image[0, 0] == pytest.approx(150 * 0.6, abs=1.5)
    assert image[0, 160] == pytest.approx(150 * (1 - 0.4 * 0.36), abs=1.5)  # (120/200)^2


def edge_width_px(row: np.ndarray) -> float:
    """10 %..90 % rise of a dark-to-light step along `row`, pixels."""
    low, high = row[:10].mean(), row[-10:].mean()
    t = (row - low) / (high - low)
    return float(np.argmax(t >= 0.9) - np.argmax(t >= 0.1))


#: Looking straight down: floor lines are straight lines through the image.
DOWN = CameraModel(width_px=640, height_px=480, pitch_down_deg=85.0, dist_coeffs=(0.0,) * 5)


def test_lens_blur_widens_an_edge_by_its_spot() -> None:
    widths = []
    for blur in (0.0, 4.0):
        renderer = renderer_for(camera_spec(optics={"blur_mrad": blur},
                                            exposure={"auto": False}),
                                step_texture(0.0, res=0.0005, size_m=2.0), camera=DOWN)
        image = render(renderer, 0.0, noise=False).astype(float)
        widths.append(edge_width_px(image[240, 280:360][::-1]))
    # sigma = 4 mrad x 457 px focal = 1.83 px: a Gaussian's 10..90 % rise is 2.56 sigma
    assert widths[0] <= 2.0
    assert widths[1] == pytest.approx(math.hypot(widths[0], 2.56 * 1.83), abs=1.0)


def test_chromatic_fringes_split_red_from_blue_towards_the_edges() -> None:
    camera = DOWN
    texture = step_texture(-0.15, res=0.001, size_m=2.0)
    texture = GroundTexture(gray=texture.gray, bgr=np.repeat(texture.gray[:, :, None], 3, 2),
                            m_per_px=texture.m_per_px, x_min=texture.x_min, y_max=texture.y_max,
                            fill_gray=40, fill_bgr=(40, 40, 40))
    renderer = renderer_for(camera_spec(optics={"chromatic": 0.005}, exposure={"auto": False}),
                            texture, camera=camera)
    image = render(renderer, 0.0, noise=False, color=True).astype(float)
    row = 240
    # the light side is left of the edge: find where each channel falls to half
    cols = np.arange(640)

    def edge(channel: int) -> float:
        profile = image[row, :, channel]
        half = (profile[:200].mean() + profile[-40:].mean()) / 2
        falling = np.nonzero((profile[:-1] >= half) & (profile[1:] < half))[0][-1]
        a, b = profile[falling], profile[falling + 1]
        return float(cols[falling] + (a - half) / (a - b))

    red, green, blue = edge(2), edge(1), edge(0)
    # red magnified by 0.5 %, blue shrunk by it, about the centre (319.5, 239.5)
    radius = green - 319.5
    assert radius > 120
    assert red - green == pytest.approx(0.005 * radius, abs=0.25)
    assert green - blue == pytest.approx(0.005 * radius, abs=0.25)


def blockiness(image: np.ndarray) -> float:
    """Mean jump across 8-pixel block boundaries over the mean jump inside blocks."""
    jumps = np.abs(np.diff(image.astype(float), axis=1))
    at_boundary = jumps[:, 7::8].mean()
    inside = np.delete(jumps, np.s_[7::8], axis=1).mean()
    return float(at_boundary / inside)


def test_jpeg_compression_shows_its_blocks_at_low_quality() -> None:
    camera = CameraModel(width_px=320, height_px=240, pitch_down_deg=80.0)
    rng = np.random.default_rng(0)
    texture = flat_texture(128)
    texture.gray[:] = cv2.GaussianBlur(rng.integers(60, 200, texture.gray.shape).astype(
        np.uint8), (0, 0), 3)
    ratios = []
    for compression in ({"format": "none"}, {"format": "jpeg", "quality": 90},
                        {"format": "jpeg", "quality": 15}):
        renderer = renderer_for(camera_spec(compression=compression), texture, camera=camera)
        ratios.append(blockiness(render(renderer, 0.0)))
    assert ratios[0] == pytest.approx(1.0, abs=0.1)
    assert ratios[2] > 1.5 and ratios[2] > ratios[1]


def dark_run(row: np.ndarray) -> int:
    """Pixels darkened at all (a smear spreads the stripe thinner)."""
    return int((row < 196).sum())


def test_motion_blur_smears_by_speed_and_turn_rate_over_the_shutter_time() -> None:
    # a dark stripe across the view 0.7 m ahead and one along it: driving smears the first
    # (vertically), turning the second (sideways); a 50 ms shutter (at gain 1: 5 x the light of
    # 10 ms on a floor of 40)
    texture = flat_texture(40)
    cols = np.arange(texture.gray.shape[1]) * RES + texture.x_min
    rows = texture.y_max - np.arange(texture.gray.shape[0]) * RES
    texture.gray[:, np.abs(cols - 0.7) < 0.01] = 5
    texture.gray[np.abs(rows) < 0.01, :] = 5
    spec = camera_spec(motion_blur=True, exposure={"auto": False, "exposure_s": 0.05})
    renderer = renderer_for(spec, texture)
    centre = CAMERA.project_ground(np.array([[0.7, 0.0]]))[0].round().astype(int)

    def widths(velocity: tuple[float, float]) -> tuple[int, int]:
        image = render(renderer, None, velocity=velocity, noise=False)
        across = image[centre[1] + 20, centre[0] - 40:centre[0] + 40]  # the stripe along x
        along = image[centre[1] - 30:centre[1] + 30, centre[0] - 30]  # the stripe across
        return dark_run(across), dark_run(along)

    still = widths((0.0, 0.0))
    turning = widths((0.0, 1.5))
    driving = widths((0.5, 0.0))
    # turning at 1.5 rad/s for 50 ms: 0.075 rad = 17 px at a 228 px focal length
    assert turning[0] - still[0] == pytest.approx(17, abs=2)
    assert turning[1] == still[1]
    # driving 0.5 m/s for 50 ms: 25 mm, some 4 px at 0.7 m ahead
    assert driving[1] - still[1] == pytest.approx(4, abs=1.5) and driving[0] == still[0]


def subpixel_edge(row: np.ndarray, level: float = 130.0) -> float:
    """Where `row` first falls below `level` (interpolated), pixels."""
    profile = row.astype(float)
    i = int(np.argmax(profile < level))
    a, b = profile[i - 1], profile[i]
    return float(i - 1 + (a - level) / (a - b))


@pytest.mark.parametrize("velocity", [(0.0, 1.0), (0.4, -0.6)])
def test_rolling_shutter_reads_each_row_where_the_robot_was_then(
        velocity: tuple[float, float]) -> None:
    """Row r of a rolling-shutter frame is row r of a global-shutter frame taken
    (r / (H - 1) - 0.5) x readout later, when the moving robot was elsewhere."""
    texture = step_texture(0.0)  # light left of the lane's centre line
    readout = 0.03
    rolling = renderer_for(camera_spec(rolling_shutter_s=readout, exposure={"auto": False}),
                           texture)
    still = renderer_for(camera_spec(exposure={"auto": False}), texture)
    skewed = render(rolling, None, velocity=velocity, noise=False)
    linear, angular = velocity
    shifts = []
    for row in (30, 235):
        dt = (row / 239 - 0.5) * readout
        # where a robot at the origin moving at `velocity` is dt later (an arc)
        theta = angular * dt
        x = linear * dt * (1.0 if abs(theta) < 1e-9 else math.sin(theta) / theta)
        y = linear * dt * (0.0 if abs(theta) < 1e-9 else (1 - math.cos(theta)) / theta)
        then = render(still, None, pose=Pose2D(x, y, theta), noise=False)
        now = render(still, None, noise=False)
        assert subpixel_edge(skewed[row]) == pytest.approx(subpixel_edge(then[row]), abs=0.3)
        shifts.append(subpixel_edge(skewed[row]) - subpixel_edge(now[row]))
    # against a global shutter the rows read before mid-frame move one way, those after the other
    assert shifts[0] * shifts[1] < 0 and min(abs(shifts[0]), abs(shifts[1])) > 0.5


def test_highlights_move_with_the_robot_and_paint_does_not() -> None:
    # One ceiling light 2.6 m up at (3, 0); a camera 0.4 m up sees its reflection where the ray
    # to its mirror image meets the floor: 0.4 / 3.0 of the way from the camera to it.
    ceiling = CeilingLightsSpec(height_m=2.6, spacing_m=(40.0, 40.0), offset_m=(3.0, 0.0),
                                size_m=0.4, strength=3.0)  # dim: a highlight, not saturated
    texture = flat_texture(120, gloss=200)
    texture.gray[:, 700:704] = 20  # a painted line across the floor at x = 0.8 m
    highlights = Highlights(ceiling, CAMERA, 0.02)
    ground_x, _ = CAMERA.pixel_ground_points()

    def bright_spot_and_line(x_m: float) -> tuple[float, float]:
        pose = Pose2D(x_m, 0.0, 0.0)
        renderer = renderer_for(camera_spec(exposure={"auto": False}), texture,
                                highlights=highlights)
        image = render(renderer, None, pose=pose, noise=False).astype(float)
        shine = np.clip(image - 120.0, 0.0, None)
        shine[image < 100] = 0.0
        ys, xs = np.mgrid[0:image.shape[0], 0:image.shape[1]]
        spot = (int(round((shine * ys).sum() / shine.sum())),
                int(round((shine * xs).sum() / shine.sum())))
        line = np.argmin(image[:, 160])
        return x_m + float(ground_x[spot]), x_m + float(ground_x[line, 160])

    spot0, line0 = bright_spot_and_line(0.0)
    spot1, line1 = bright_spot_and_line(0.2)
    camera_x = CAMERA.position_robot()[0]
    assert spot0 == pytest.approx(camera_x + (3.0 - camera_x) * 0.4 / 3.0, abs=0.03)
    assert spot1 - spot0 == pytest.approx(0.2 * 2.6 / 3.0, abs=0.02)  # moved with the robot
    assert line1 - line0 == pytest.approx(0.0, abs=0.01)  # the paint stayed


def test_a_matte_floor_shows_no_highlight() -> None:
    ceiling = CeilingLightsSpec(spacing_m=(1.0, 1.0))
    highlights = Highlights(ceiling, CAMERA, 0.02)
    matte = renderer_for(camera_spec(exposure={"auto": False}), flat_texture(120, gloss=0),
                         highlights=highlights)
    assert render(matte, None, noise=False).max() <= 121


def test_light_changes_ramp_between_brightness_and_colour() -> None:
    lighting = LightingSpec(brightness=1.0, changes=[
        {"at_s": 2.0, "ramp_s": 1.0, "brightness": 0.5, "color": "#ff0000"}])
    assert light_at(lighting, 1.9).brightness == 1.0
    halfway = light_at(lighting, 2.5)
    assert halfway.brightness == pytest.approx(0.75)
    assert halfway.tint_bgr == pytest.approx((0.5, 0.5, 1.0))
    assert light_at(lighting, 9.0).tint_bgr == pytest.approx((0.0, 0.0, 1.0))
