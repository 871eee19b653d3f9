"""The documentation site builds with no warning (``mkdocs build --strict``), every local file its pages
reference exists, nothing is loaded from outside it, and headless Chromium (Debian's ``chromium``) renders
its front page and an API page: screenshots that are not blank and show the theme's colours, so its
stylesheets loaded."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from html.parser import HTMLParser
from pathlib import Path
from urllib.parse import unquote, urlsplit

import imageio.v3 as iio
import numpy as np
import pytest

ROOT = Path(__file__).parents[1]
PAGES = ("index.html", "api/envs.html")
# Material's "teal" primary colour, the header bar's: present only if the theme's stylesheets loaded.
HEADER_RGB = (0x00, 0x94, 0x85)


class _References(HTMLParser):
    """Every href and src of a page: (tag, rel, url)."""

    def __init__(self) -> None:
        super().__init__()
        self.found: list[tuple[str, str, str]] = []

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        values = dict(attrs)
        for key in ("href", "src"):
            if values.get(key):
                self.found.append((tag, values.get("rel") or "", values[key]))


@pytest.fixture(scope="module")
def site(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("site")
    env = {**os.environ, "NO_MKDOCS_2_WARNING": "1"}
    done = subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(out)],
        cwd=ROOT,
        env=env,
        capture_output=True,
        text=True,
    )
    assert done.returncode == 0, done.stderr
    return out


@pytest.mark.parametrize("page", PAGES)
def test_every_local_reference_exists_and_nothing_comes_from_outside(site: Path, page: str) -> None:
    parser = _References()
    parser.feed((site / page).read_text())
    assets = [url for tag, rel, url in parser.found if tag in ("script", "img") or "stylesheet" in rel]
    assert any(url.endswith(".css") for url in assets) and any(url.endswith(".js") for url in assets)
    for tag, _, url in parser.found:
        parts = urlsplit(url)
        if parts.scheme or parts.netloc:
            # Outside links are fine to follow, not to load: a page must render offline.
            assert tag == "a" and parts.scheme == "https", f"{page} loads {url} from outside the site"
            continue
        if parts.path:
            target = (site / page).parent / unquote(parts.path)
            assert target.is_file(), f"{page}: {tag} {url} -> {target} does not exist"


def _chromium() -> str:
    found = shutil.which("chromium")
    if found is None:
        if os.environ.get("CI"):
            pytest.fail("chromium is not installed (.ci/run installs Debian's package)")
        pytest.skip("chromium is not installed: apt-get install chromium")
    return found


@pytest.mark.parametrize("page", PAGES)
def test_chromium_renders_the_page(site: Path, page: str, tmp_path: Path) -> None:
    chromium = _chromium()
    shot = tmp_path / "page.png"
    # file:// URLs: nothing is served. --no-sandbox because CI runs as root.
    flags = ["--headless", "--no-sandbox", "--disable-gpu", "--no-first-run", "--hide-scrollbars"]
    flags += ["--disable-background-networking", f"--user-data-dir={tmp_path / 'profile'}"]
    flags.append("--window-size=1280,900")
    url = (site / page).as_uri()
    done = subprocess.run(
        [chromium, *flags, f"--screenshot={shot}", url], capture_output=True, text=True, timeout=120
    )
    assert done.returncode == 0 and shot.is_file(), done.stderr
    pixels = iio.imread(shot)[..., :3].astype(int)
    assert pixels.shape[:2] == (900, 1280)
    colours = np.unique(pixels.reshape(-1, 3), axis=0)
    assert len(colours) > 50 and pixels.std() > 20, f"{page} rendered blank"
    header = (np.abs(pixels - HEADER_RGB).sum(axis=-1) < 12).mean()
    assert header > 0.03, f"{page}: {header:.1%} of the screenshot in the theme's header colour"

    dom = subprocess.run([chromium, *flags, "--dump-dom", url], capture_output=True, text=True, timeout=120)
    assert dom.returncode == 0, dom.stderr
    expected = "hier_ssl.envs.parallel_env" if page.startswith("api/") else "Getting started"
    assert expected in dom.stdout


def test_every_markdown_page_closes_its_code_blocks() -> None:
    # An unclosed fence does not stop a build: the rest of the page would render as code.
    for page in [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]:
        fences = [line for line in page.read_text().splitlines() if line.lstrip().startswith("```")]
        assert len(fences) % 2 == 0, f"{page.relative_to(ROOT)}: {len(fences)} fence lines"
        assert all(f.strip() != "```" for f in fences[::2]), (
            f"{page.relative_to(ROOT)}: a block without a language"
        )
