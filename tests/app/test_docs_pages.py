"""``/docs`` (Swagger UI) and ``/redoc`` work offline: their pages load scripts and styles
from the service itself, never from a CDN, and those files are served."""

from __future__ import annotations

import re

import pytest


def _asset_urls(html: str) -> list[str]:
    """Every URL a page's tags load (src, href) and every absolute URL in its text."""
    return re.findall(r'(?:src|href)\s*=\s*"([^"]+)"', html) + re.findall(r"https?://[^\s'\"<>)]+",
                                                                          html)


@pytest.mark.parametrize("page", ["/docs", "/redoc"])
def test_docs_pages_load_only_local_assets(ro_client, page):
    r = ro_client.get(page)
    assert r.status_code == 200 and r.headers["content-type"].startswith("text/html")
    urls = _asset_urls(r.text)
    assert any(u.endswith(".js") for u in urls), urls
    for url in urls:
        assert url.startswith("/") and not url.startswith("//"), url


def test_swagger_ui_assets_are_served(ro_client):
    html = ro_client.get("/docs").text
    js = re.findall(r'<script src="([^"]+)"', html)
    css = re.findall(r'<link[^>]*rel="stylesheet"[^>]*href="([^"]+)"', html) or \
        re.findall(r'<link[^>]*href="([^"]+\.css)"', html)
    assert js and css
    for url in js:
        r = ro_client.get(url)
        assert r.status_code == 200 and "javascript" in r.headers["content-type"]
        assert len(r.content) > 100_000 and b"SwaggerUIBundle" in r.content
    for url in css:
        r = ro_client.get(url)
        assert r.status_code == 200 and r.headers["content-type"].startswith("text/css")
        assert b".swagger-ui" in r.content
    assert "/openapi.json" in html


def test_swagger_ui_reads_openapi_3_1(ro_client):
    """The bundled Swagger UI is of the 5.x line, the first to render OpenAPI 3.1 documents
    (4.x shows 'Unable to render this definition' for them)."""
    assert ro_client.get("/openapi.json").json()["openapi"].startswith("3.1")
    js_url = re.findall(r'<script src="([^"]+)"', ro_client.get("/docs").text)[0]
    bundle = ro_client.get(js_url).text
    versions = set(re.findall(r'"(5\.\d+\.\d+)"', bundle))
    assert versions, "no Swagger UI 5.x version string in the bundle"


def test_redoc_script_is_served(ro_client):
    html = ro_client.get("/redoc").text
    (js,) = re.findall(r'<script src="([^"]+)"', html)
    r = ro_client.get(js)
    assert r.status_code == 200 and "javascript" in r.headers["content-type"]
    assert b"redoc" in r.content[:5000].lower() or b"Redoc" in r.content
    assert "fonts.googleapis.com" not in html


def test_oauth2_redirect_page_is_served(ro_client):
    r = ro_client.get("/docs/oauth2-redirect")
    assert r.status_code == 200 and "text/html" in r.headers["content-type"]
