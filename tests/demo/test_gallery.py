"""stbs.demo.gallery: the self-contained index.html of the demo's figures."""

from __future__ import annotations

import re
from html.parser import HTMLParser

import pytest

from stbs.demo.gallery import GalleryEntry, write_gallery


class Collect(HTMLParser):
    """Tags with their attributes, and the page's visible text."""

    def __init__(self):
        super().__init__()
        self.tags: list[tuple[str, dict]] = []
        self.text: list[str] = []

    def handle_starttag(self, tag, attrs):
        self.tags.append((tag, dict(attrs)))

    def handle_data(self, data):
        self.text.append(data)


def parse(html: str) -> Collect:
    c = Collect()
    c.feed(html)
    return c


def entries() -> list[GalleryEntry]:
    return [
        GalleryEntry(
            "box", "Fig. 3 left: one bone twisted 315 degrees",
            "STBS spreads the twist along the bone; LBS and DQS turn the box rigidly.\n"
            "Look at the middle cross-section.",
            images=["box.png", "box twist.gif"],
            table={"lbs": {"mid twist": 315.0, "far twist": 315.0},
                   "stbs-dqs": {"mid twist": 157.5123, "far twist": "315 (exact)"}},
            columns=["mid twist", "far twist"],
            expected={"mid twist": "STBS 157.5", "far twist": "315"}),
        GalleryEntry(
            "cigar", "Fig. 2: <script>alert('x')</script> & stretch", "caption with <b>",
            images=["cigar.png"], table=[["lbs", 2.0], ["stbs-lbs", 1.0]],
            columns=["tip length"], expected="LBS doubles the tip; STBS keeps it (1)"),
    ]


@pytest.fixture
def out(tmp_path):
    for name in ("box.png", "box twist.gif", "cigar.png"):
        (tmp_path / name).write_bytes(b"\x89PNG fake")
    return tmp_path


def test_index_links_every_image_with_alt_text(out):
    path = write_gallery(out, entries(), intro="Three cases from the paper.")
    assert path == out / "index.html"
    page = parse(path.read_text(encoding="utf-8"))
    imgs = [a for t, a in page.tags if t == "img"]
    assert [a["src"] for a in imgs] == ["box.png", "box%20twist.gif", "cigar.png"]
    assert all(a["alt"] for a in imgs)
    links = {a["href"] for t, a in page.tags if t == "a"}
    assert {"box.png", "box%20twist.gif", "cigar.png", "#box", "#cigar"} <= links
    ids = [a["id"] for t, a in page.tags if t == "section"]
    assert ids == ["box", "cigar"]


def test_text_is_escaped(out):
    html = write_gallery(out, entries(), title="demo <script>x</script>").read_text()
    assert "<script" not in html
    assert "&lt;script&gt;alert(&#x27;x&#x27;)&lt;/script&gt; &amp; stretch" in html
    assert "caption with &lt;b&gt;" in html
    assert "<title>demo &lt;script&gt;x&lt;/script&gt;</title>" in html


def test_table_shows_numbers_and_expected(out):
    html = write_gallery(out, entries()).read_text()
    text = " ".join(parse(html).text)
    for s in ("mid twist", "far twist", "157.5", "315 (exact)", "STBS 157.5", "tip length",
              "expected: LBS doubles the tip; STBS keeps it (1)"):
        assert s in text, s
    rows = re.findall(r"<tr>(.*?)</tr>", html)
    assert "<td>stbs-dqs</td><td>157.5</td><td>315 (exact)</td>" in rows
    assert "<td>lbs</td><td>2</td>" in rows
    assert '<tr class="expected"><td>expected</td><td>STBS 157.5</td><td>315</td></tr>' in html


def test_page_is_self_contained(out):
    html = write_gallery(out, entries()).read_text()
    assert "<style>" in html
    assert not re.search(r"https?://|<script|<link|src=\"/|@import", html)


def test_write_is_atomic_and_replaces(out):
    (out / "index.html").write_text("old")
    write_gallery(out, entries())
    assert (out / "index.html").read_text().startswith("<!DOCTYPE html>")
    assert sorted(p.name for p in out.iterdir()) == ["box twist.gif", "box.png", "cigar.png",
                                                       "index.html"]


def test_missing_or_unsafe_images_are_refused(out):
    with pytest.raises(FileNotFoundError, match=r"entry 'x': image 'nope.png' not found"):
        write_gallery(out, [GalleryEntry("x", "t", images=["nope.png"])])
    write_gallery(out, [GalleryEntry("x", "t", images=["nope.png"])], check_images=False)
    for bad in ("../up.png", "/abs.png", "https://example.com/a.png", "C:/x.png"):
        with pytest.raises(ValueError, match=r"images\[0\] must be a file name relative"):
            GalleryEntry("x", "t", images=[bad])
    with pytest.raises(FileNotFoundError, match=r"out_dir must be an existing folder"):
        write_gallery(out / "missing", [])


def test_bad_entries(out):
    with pytest.raises(ValueError, match=r"name must be letters"):
        GalleryEntry("a b", "t")
    with pytest.raises(ValueError, match=r"table\[0\] must be a row \[method, 2 values\]"):
        GalleryEntry("a", "t", table=[["lbs", 1.0]], columns=["p", "q"])
    with pytest.raises(ValueError, match=r"table\['lbs'\] names columns not in columns"):
        GalleryEntry("a", "t", table={"lbs": {"r": 1}}, columns=["p"])
    with pytest.raises(ValueError, match=r"expected names columns not in columns"):
        GalleryEntry("a", "t", columns=["p"], expected={"q": "1"})
    with pytest.raises(ValueError, match=r"entries\[1\].name 'a' is used twice"):
        write_gallery(out, [GalleryEntry("a", "t"), GalleryEntry("a", "u")])
    with pytest.raises(ValueError, match=r"entries\[0\] must be a GalleryEntry, got dict"):
        write_gallery(out, [{"name": "a"}])
