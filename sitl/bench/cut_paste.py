"""Training frames made the "cut, paste and learn" way (Dwibedi et al. 2017): rendered multirotors of
many designs pasted over photographs, so the detector learns drones rather than one renderer's world.

The drones are :func:`sitl.world.camera.models.random_multirotor` designs drawn by the renderer's own
model drawing (:func:`sitl.world.camera.renderer.draw_model`), seen from 70 degrees below to 85 above,
tilted as a flying multirotor is, 4-80 px across, lit by a random sun, sometimes backlit to a
silhouette or faded by haze; the coverage of each pixel comes from a second, white drawing, so the
paste is anti-aliased and the spinning rotors stay translucent. A label is the tight box of the
pixels at least 20 % covered. For the search-and-rescue detector the same is done with people of
random build and dress, standing or lying, seen from 25-88 degrees above over ground photographs.
Birds (dark or pale, wings up, down or spread), drawn here, are pasted unlabelled as the negatives
they are in the field.

The backgrounds are the user's photographs (:class:`PhotoLibrary`): folders, image files, or zip
archives such as a game's ``.pk3`` texture pack. The docs name Debian packages of landscape
wallpapers and ground textures that serve. The sources the project keeps for its independent tests,
scikit-image's sample images and Debian's ``trigger-rally-data``, are refused. A frame is one photo
(scaled, cropped, flipped), a ground texture tiled as seen from altitude, or a sky over a horizon.
"""

from __future__ import annotations

import logging
import math
import zipfile
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Callable, Sequence

import cv2
import numpy as np
from scipy.spatial.transform import Rotation

from sitl.world.camera.models import PERSON_HEIGHT_M, TargetModel, random_multirotor, random_person
from sitl.world.camera.renderer import compile_model, draw_model

__all__ = ["RESERVED_SOURCES", "KINDS", "PhotoLibrary", "CutPasteFrame", "CutPaste", "draw_drone", "draw_person", "write_folder"]

log = logging.getLogger(__name__)

#: Path parts of the photograph sources kept for independent tests: never training backgrounds.
RESERVED_SOURCES = ("skimage", "scikit-image", "scikit_image", "trigger-rally", "trigger_rally")
_IMAGE_SUFFIXES = (".jpg", ".jpeg", ".png", ".webp", ".bmp")
#: Texture maps that are not pictures of anything (normal, gloss, specular, bump, height maps).
_NOT_PICTURES = ("_nm.", "_gm.", "_sm.", "_bump", "_height", "_normal", "_spec", "_gloss")
_SUPERSAMPLE = 3
#: What a frame's labels are: drones, or people on the ground for the search-and-rescue detector.
KINDS = ("drone", "person")


def _reserved(path: str) -> bool:
    return any(part in path.lower() for part in RESERVED_SOURCES)


class PhotoLibrary:
    """Photographs to paste onto, read from ``sources`` (image files, folders searched recursively, zip
    archives), each shrunk to at most ``max_side`` px, those unreadable or narrower than ``min_side`` px
    dropped and counted (``dropped``), texture maps that are not pictures skipped and counted
    (``maps_skipped``); at most ``limit`` (a seeded random choice) are kept in memory.

    Raises:
        ValueError: a source is one of :data:`RESERVED_SOURCES`, or no usable photograph was found.
    """

    def __init__(self, sources: Sequence[str | Path], min_side: int = 192, max_side: int = 1280, limit: int = 800,
                 seed: int = 0) -> None:
        entries: list[tuple[str, str | None]] = []  # (file or archive, member)
        for src in map(Path, sources):
            if src.is_dir():
                entries += [(str(p), None) for p in sorted(src.rglob("*")) if p.suffix.lower() in _IMAGE_SUFFIXES]
            elif zipfile.is_zipfile(src):
                with zipfile.ZipFile(src) as z:
                    entries += [(str(src), n) for n in sorted(z.namelist()) if Path(n).suffix.lower() in _IMAGE_SUFFIXES]
            elif src.is_file():
                entries.append((str(src), None))
            else:
                raise ValueError(f"{src}: no such photograph, folder or archive")
        for path, member in entries:
            if _reserved(f"{Path(path).resolve()}/{member or ''}"):  # resolved: a link into one is refused too
                raise ValueError(f"{path}{':' + member if member else ''}: a photograph source kept for independent "
                                 "tests; never train on it")
        pictures = [e for e in entries if not any(m in (e[1] or e[0]).lower() for m in _NOT_PICTURES)]
        self.maps_skipped = len(entries) - len(pictures)
        entries = pictures
        order = np.random.default_rng(seed).permutation(len(entries))
        self.photos: list[np.ndarray] = []
        self.names: list[str] = []
        self.dropped = 0
        archives: dict[str, zipfile.ZipFile] = {}
        for k in order:
            if len(self.photos) >= limit:
                break
            path, member = entries[int(k)]
            if member is None:
                img = cv2.imread(path, cv2.IMREAD_COLOR)
            else:
                z = archives.setdefault(path, zipfile.ZipFile(path))
                img = cv2.imdecode(np.frombuffer(z.read(member), np.uint8), cv2.IMREAD_COLOR)
            if img is None or min(img.shape[:2]) < min_side:
                self.dropped += 1
                continue
            s = min(1.0, max_side / max(img.shape[:2]))
            if s < 1.0:
                img = cv2.resize(img, (round(img.shape[1] * s), round(img.shape[0] * s)), interpolation=cv2.INTER_AREA)
            self.photos.append(img)
            self.names.append(f"{path}:{member}" if member else path)
        for z in archives.values():
            z.close()
        if not self.photos:
            raise ValueError(f"no usable photograph in {', '.join(map(str, sources))} "
                             f"({self.dropped} unreadable or under {min_side} px)")
        log.info("%d photographs loaded, %d dropped (unreadable or under %d px), %d texture maps skipped",
                 len(self.photos), self.dropped, min_side, self.maps_skipped)


@dataclass(frozen=True)
class CutPasteFrame:
    """One training frame: BGR ``image`` and (N, 5) ``boxes`` (class 0, x0, y0, x1, y1 in pixels)."""

    image: np.ndarray
    boxes: np.ndarray


def _look_at(camera: np.ndarray) -> np.ndarray:
    """Optical -> world rotation of a camera at ``camera`` looking at the origin (world z up)."""
    f = -camera / np.linalg.norm(camera)
    right = np.cross(f, [0.0, 0.0, 1.0])
    right /= np.linalg.norm(right)
    return np.stack([right, np.cross(f, right), f], axis=1)


def _draw(model: TargetModel, rng: np.random.Generator, span_px: float, elevation_deg: tuple[float, float],
          attitude: Callable[[np.random.Generator], np.ndarray], centre_body: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``model`` (body point ``centre_body`` at the patch centre) ``span_px`` per ``model.span_m``, seen from
    a random side at an elevation in ``elevation_deg``, its body -> world rotation drawn by ``attitude``:
    (premultiplied BGR float patch, coverage in [0, 1])."""
    colour_m = compile_model(model)
    white_m = compile_model(replace(model, parts=tuple(replace(part, colour=(255, 255, 255)) for part in model.parts)))
    s = _SUPERSAMPLE
    size = int(math.ceil(span_px * 1.4 * s)) + 4 * s
    focal = 600.0 * s
    distance = focal * model.span_m / (span_px * s)
    el = math.radians(rng.uniform(*elevation_deg))
    az = rng.uniform(0.0, 2 * math.pi)
    camera = distance * np.array([math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), math.sin(el)])
    r_ce = _look_at(camera)
    rot = attitude(rng)
    sun_el, sun_az = math.radians(rng.uniform(15, 80)), rng.uniform(0, 2 * math.pi)
    sun = np.array([math.cos(sun_el) * math.cos(sun_az), math.cos(sun_el) * math.sin(sun_az), math.sin(sun_el)])
    position = -rot @ centre_body
    colour = np.zeros((size, size, 3), np.uint8)
    white = np.zeros((size, size, 3), np.uint8)
    draw_model(colour, colour_m, rot, position, r_ce, camera, (focal, focal), sun, float(rng.uniform(0.7, 1.3)))
    draw_model(white, white_m, rot, position, r_ce, camera, (focal, focal), sun, 2.0)
    small = (size // s, size // s)
    patch = cv2.resize(colour, small, interpolation=cv2.INTER_AREA).astype(np.float32)
    cover = cv2.resize(white[..., 0], small, interpolation=cv2.INTER_AREA).astype(np.float32) / 255.0
    return patch, cover


def draw_drone(rng: np.random.Generator, span_px: float) -> tuple[np.ndarray, np.ndarray]:
    """A random multirotor about ``span_px`` across, seen from 70 degrees below to 85 above, tilted as in
    flight: (premultiplied BGR float patch, coverage in [0, 1])."""
    def flying(r: np.random.Generator) -> np.ndarray:
        return Rotation.from_euler("ZYX", [r.uniform(0, 360), r.normal(0, 10), r.normal(0, 10)], degrees=True).as_matrix()

    return _draw(random_multirotor(rng), rng, span_px, (-70.0, 85.0), flying, np.zeros(3))


def draw_person(rng: np.random.Generator, length_px: float) -> tuple[np.ndarray, np.ndarray]:
    """A person of a random build and dress (:func:`~sitl.world.camera.models.random_person`), 1.75 m drawn
    ``length_px`` long, standing or lying (on the back or the front), seen from 25-88 degrees above as a
    searching drone sees them: (premultiplied patch, coverage)."""
    def on_ground(r: np.random.Generator) -> np.ndarray:
        yaw = r.uniform(-math.pi, math.pi)
        if r.random() < 0.5:
            return Rotation.from_euler("Z", [yaw]).as_matrix()
        return Rotation.from_euler("ZX", [yaw, r.choice([-1.0, 1.0]) * math.pi / 2]).as_matrix()  # on the back or front

    person = replace(random_person(rng), span_m=PERSON_HEIGHT_M)
    return _draw(person, rng, length_px, (25.0, 88.0), on_ground, np.array([0.0, 0.0, PERSON_HEIGHT_M / 2]))


def _draw_bird(rng: np.random.Generator, span_px: float) -> tuple[np.ndarray, np.ndarray]:
    """A bird ``span_px`` wide: body and two wings, in one of a gull's, a crow's or a pigeon's shades."""
    s = _SUPERSAMPLE
    size = int(math.ceil(span_px * 1.2 * s)) + 4 * s
    half = size // 2
    cover = np.zeros((size, size), np.uint8)
    w = span_px * s / 2
    lift = rng.uniform(-0.5, 0.6)  # wings down .. up
    thick = max(int(round(span_px * s * rng.uniform(0.05, 0.1))), 1)
    for side in (-1, 1):
        elbow = (int(half + side * w * 0.45), int(half - lift * w * 0.5))
        cv2.line(cover, (half, half), elbow, 255, thick * 2, cv2.LINE_AA)
        cv2.line(cover, elbow, (int(half + side * w), int(half - lift * w * 0.2 + w * 0.1)), 255, thick, cv2.LINE_AA)
    cv2.ellipse(cover, (half, half), (max(int(w * 0.28), 1), max(int(w * 0.1), 1)), rng.uniform(-20, 20), 0, 360, 255, -1, cv2.LINE_AA)
    shade = float(rng.choice([35.0, 60.0, 120.0, 220.0]))
    cover_f = cv2.resize(cover, (size // s, size // s), interpolation=cv2.INTER_AREA).astype(np.float32) / 255.0
    angle = rng.uniform(0, 360)
    rot = cv2.getRotationMatrix2D((cover_f.shape[1] / 2, cover_f.shape[0] / 2), angle, 1.0)
    cover_f = cv2.warpAffine(cover_f, rot, cover_f.shape[::-1])
    patch = cover_f[..., None] * (shade * rng.uniform(0.9, 1.1, 3)).astype(np.float32)
    return patch, cover_f


class CutPaste:
    """Frames of ``width`` x ``height`` from a :class:`PhotoLibrary` (see the module docstring): targets of
    ``kind`` (:data:`KINDS`) ``span_px`` across or, people, long (log-uniform), ``empty_share`` of the
    frames without one, a Poisson(``bird_rate``) number of birds a frame, ``sky_share`` of the
    backgrounds a sky (people are seen against the ground: set it to 0 for them)."""

    def __init__(self, photos: PhotoLibrary, width: int = 640, height: int = 480, span_px: tuple[float, float] = (4.0, 80.0),
                 empty_share: float = 0.1, bird_rate: float = 0.8, sky_share: float = 0.3, kind: str = "drone") -> None:
        if kind not in KINDS:
            raise ValueError(f"cut-and-paste kind {kind!r}: one of {', '.join(KINDS)}")
        self.photos, self.width, self.height, self.kind = photos, width, height, kind
        self.span_px, self.empty_share, self.bird_rate, self.sky_share = span_px, empty_share, bird_rate, sky_share

    def _cover(self, photo: np.ndarray, rng: np.random.Generator, w: int, h: int, zoom: tuple[float, float]) -> np.ndarray:
        ph, pw = photo.shape[:2]
        scale = max(w / pw, h / ph) * rng.uniform(*zoom)
        big = cv2.resize(photo, (max(int(math.ceil(pw * scale)), w), max(int(math.ceil(ph * scale)), h)), interpolation=cv2.INTER_AREA
                         if scale < 1 else cv2.INTER_LINEAR)
        y0, x0 = int(rng.integers(big.shape[0] - h + 1)), int(rng.integers(big.shape[1] - w + 1))
        out = big[y0:y0 + h, x0:x0 + w]
        return out[:, ::-1] if rng.random() < 0.5 else out

    def _tiled(self, photo: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """A ground texture repeated as a field seen from altitude, at a random scale and rotation."""
        tile = cv2.resize(photo, None, fx=rng.uniform(0.25, 0.8), fy=rng.uniform(0.25, 0.8), interpolation=cv2.INTER_AREA)
        reps = (math.ceil(2 * self.height / tile.shape[0]) + 1, math.ceil(2 * self.width / tile.shape[1]) + 1, 1)
        field = np.tile(tile, reps)
        rot = cv2.getRotationMatrix2D((field.shape[1] / 2, field.shape[0] / 2), rng.uniform(0, 360), 1.0)
        field = cv2.warpAffine(field, rot, field.shape[1::-1], borderMode=cv2.BORDER_REFLECT)
        y0, x0 = (field.shape[0] - self.height) // 2, (field.shape[1] - self.width) // 2
        return field[y0:y0 + self.height, x0:x0 + self.width]

    def _sky(self, rng: np.random.Generator) -> np.ndarray:
        """A sky (clear blue, hazy, overcast grey) over a photograph below a horizon, or sky alone."""
        h, w = self.height, self.width
        top = np.array(rng.choice([[205, 150, 95], [225, 195, 165], [200, 200, 200], [150, 150, 155]]), np.float32)  # BGR
        bottom = np.clip(top + rng.uniform(20, 60), 0, 255)
        t = np.linspace(0.0, 1.0, h, dtype=np.float32)[:, None, None]
        sky = (top * (1 - t) + bottom * t) * (rng.uniform(0.95, 1.05, 3) * rng.uniform(0.8, 1.15)).astype(np.float32)
        sky = np.broadcast_to(sky, (h, w, 3)).copy()
        if rng.random() < 0.6:  # clouds: smooth noise lightening the sky
            noise = cv2.resize(rng.random((max(h // 40, 2), max(w // 40, 2))).astype(np.float32), (w, h), interpolation=cv2.INTER_CUBIC)
            sky += (np.clip(noise - rng.uniform(0.3, 0.6), 0, 1) * rng.uniform(60, 160))[..., None]
        if rng.random() < 0.6:
            horizon = int(h * rng.uniform(0.45, 0.95))
            ground = self._cover(self.photos.photos[int(rng.integers(len(self.photos.photos)))], rng, w, h - horizon, (1.0, 2.0))
            sky[horizon:] = ground
        return sky

    def _background(self, rng: np.random.Generator) -> np.ndarray:
        mode = rng.random()
        if mode < self.sky_share:
            img = self._sky(rng)
        else:  # a fifth of the frames a tiled ground texture, and every photograph too small to cover the frame
            photo = self.photos.photos[int(rng.integers(len(self.photos.photos)))]
            small = max(photo.shape[:2]) < max(self.width, self.height)
            tiled = small or mode < self.sky_share + 0.2
            img = self._tiled(photo, rng) if tiled else self._cover(photo, rng, self.width, self.height, (1.0, 2.5))
        img = img.astype(np.float32) * (rng.uniform(0.9, 1.1, 3) * rng.uniform(0.7, 1.2)).astype(np.float32)
        return np.clip(img, 0, 255)

    def _paste(self, img: np.ndarray, patch: np.ndarray, cover: np.ndarray, rng: np.random.Generator) -> tuple[int, int] | None:
        ph, pw = cover.shape
        if pw >= self.width or ph >= self.height:
            return None
        x0, y0 = int(rng.integers(self.width - pw)), int(rng.integers(self.height - ph))
        region = img[y0:y0 + ph, x0:x0 + pw]
        region[:] = region * (1 - cover[..., None]) + patch
        return x0, y0

    def sample(self, rng: np.random.Generator) -> CutPasteFrame:
        """One frame: none (``empty_share``) to three targets and a Poisson(``bird_rate``) number of birds."""
        img = self._background(rng)
        boxes = []
        for _ in range(rng.poisson(self.bird_rate)):
            self._paste(img, *_draw_bird(rng, float(np.exp(rng.uniform(math.log(5), math.log(40))))), rng)
        count = 0 if rng.random() < self.empty_share else int(rng.choice([1, 1, 1, 2, 3]))
        lo, hi = (math.log(v) for v in self.span_px)
        for _ in range(count):
            patch, cover = (draw_person if self.kind == "person" else draw_drone)(rng, float(np.exp(rng.uniform(lo, hi))))
            if self.kind == "drone" and rng.random() < 0.25:  # backlit against the sky: a silhouette
                patch *= rng.uniform(0.15, 0.5)
            haze = rng.uniform(0.0, 0.35) if rng.random() < 0.4 else 0.0
            patch = patch * (1 - haze) + cover[..., None] * haze * img.reshape(-1, 3).mean(axis=0)
            at = self._paste(img, patch, cover, rng)
            ys, xs = np.nonzero(cover >= 0.2)
            if at is not None and len(xs):
                boxes.append([0, at[0] + xs.min(), at[1] + ys.min(), at[0] + xs.max() + 1, at[1] + ys.max() + 1])
        if rng.random() < 0.7:
            img = cv2.GaussianBlur(img, (0, 0), rng.uniform(0.3, 1.0))
        img = img + rng.normal(0.0, rng.uniform(0.5, 5.0), img.shape).astype(np.float32)
        ok, jpg = cv2.imencode(".jpg", np.clip(img, 0, 255).astype(np.uint8), [cv2.IMWRITE_JPEG_QUALITY, int(rng.integers(60, 96))])
        if not ok:
            raise RuntimeError("JPEG encoding failed")
        return CutPasteFrame(cv2.imdecode(jpg, cv2.IMREAD_COLOR), np.array(boxes, float).reshape(-1, 5))


def write_folder(out: str | Path, sources: Sequence[str | Path], count: int, seed: int, kind: str = "drone") -> Path:
    """``count`` cut-and-paste frames of ``kind`` over the photographs in ``sources`` as a YOLO folder (one
    class, ``drone`` or ``person``) that ``chaser-bt train-detector`` reads; people are 10-80 px long, on
    ground photographs only."""
    from chaser_bt.vision.footage.yolo_folder import box_line, prepare_parts, write_example

    root = Path(out)
    people = kind == "person"
    maker = CutPaste(PhotoLibrary(sources, seed=seed), span_px=(10.0, 80.0) if people else (4.0, 80.0),
                     sky_share=0.0 if people else 0.3, kind=kind)
    prepare_parts(root, ("",), (kind,))
    rng = np.random.default_rng(seed)
    step = max(count // 20, 1)
    for k in range(count):
        frame = maker.sample(rng)
        h, w = frame.image.shape[:2]
        lines = [box_line(0, x0, y0, x1, y1, w, h) for _, x0, y0, x1, y1 in frame.boxes]
        write_example(root, f"cut_{k:06d}", frame.image, [x for x in lines if x is not None])
        if (k + 1) % step == 0:
            log.info("cut-and-paste frames: %d/%d", k + 1, count)
    return root


def main(argv: list[str] | None = None) -> int:
    import argparse

    p = argparse.ArgumentParser(prog="python -m sitl.bench.cut_paste", description=write_folder.__doc__)
    p.add_argument("out", help="folder to write (images/, labels/, classes.txt)")
    p.add_argument("--photos", nargs="+", required=True, metavar="PATH",
                   help="photograph files, folders or zip archives to paste onto (docs/vision.md names Debian packages)")
    p.add_argument("--count", type=int, default=3000)
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--kind", choices=KINDS, default="drone", help="what the frames hold (default drone)")
    args = p.parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    try:
        print(write_folder(args.out, args.photos, args.count, args.seed, args.kind))
    except ValueError as e:
        p.error(str(e))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
