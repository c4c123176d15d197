"""The style sheet and script inlined into the leaderboard page (:mod:`leaderboard.output.webpage`).

Both are plain text copied verbatim into ``index.html`` (no templating: nothing of the data enters them). The script
sorts a table by the column header clicked (numbers numerically, by the cell's ``data-value``; empty cells last;
a second click reverses), filters rows by task, track, kind and safety filter (``data-*`` attributes of the
sections and rows), shows an entry's details (its ``<template>``) in an overlay, and fills every ``img[data-plot]``
from the page's embedded plot data (``data:`` URIs, so a plot shared by two entries is embedded once).
"""

from __future__ import annotations

CSS = """
:root { --fg: #1d2330; --muted: #5b6578; --line: #d5dae3; --head: #eef1f6; --accent: #1f5fbf; --bg: #ffffff; }
* { box-sizing: border-box; }
body { margin: 0; font: 14px/1.45 system-ui, -apple-system, "Segoe UI", Roboto, sans-serif; color: var(--fg);
       background: var(--bg); }
header, main, #plots, #controls, #generalization { padding: 0 1.5rem; }
header h1 { margin: 1rem 0 0.3rem; font-size: 1.6rem; }
header p, .note { color: var(--muted); max-width: 72rem; }
details.generated { color: var(--muted); margin-bottom: 0.6rem; max-width: 72rem; }
#controls { position: sticky; top: 0; z-index: 2; background: var(--bg); border-bottom: 1px solid var(--line);
            display: flex; flex-wrap: wrap; gap: 0.4rem 1.2rem; align-items: center; padding-top: 0.5rem;
            padding-bottom: 0.5rem; }
#controls label { color: var(--muted); }
#controls select { font: inherit; margin-left: 0.3rem; }
#shown-count { margin-left: auto; color: var(--muted); }
section.board { margin: 1.2rem 0 1.6rem; }
section.board h2 { font-size: 1.15rem; margin: 0 0 0.4rem; }
section.board h2 small { color: var(--muted); font-weight: normal; }
.table-wrap { overflow-x: auto; }
table { border-collapse: collapse; }
table.ranking { min-width: 60rem; }
th, td { border-bottom: 1px solid var(--line); padding: 0.25rem 0.55rem; text-align: left; vertical-align: top; }
th { background: var(--head); font-weight: 600; white-space: nowrap; }
table.ranking th { cursor: pointer; user-select: none; }
table.ranking th:hover { color: var(--accent); }
table.ranking th[aria-sort="ascending"]::after { content: " \\25B2"; font-size: 0.75em; }
table.ranking th[aria-sort="descending"]::after { content: " \\25BC"; font-size: 0.75em; }
td.num { text-align: right; white-space: nowrap; font-variant-numeric: tabular-nums; }
td.empty { color: var(--muted); }
.extra { display: none; }
body.show-extra .extra { display: table-cell; }
td.extra { white-space: nowrap; }
button.entry-link { font: inherit; color: var(--accent); background: none; border: none; padding: 0; cursor: pointer;
                    text-align: left; text-decoration: underline dotted; }
.kind, td.entry { white-space: nowrap; }
#plots figure { margin: 0 0 1.2rem; }
#plots .plot-wrap { overflow-x: auto; border: 1px solid var(--line); }
#plots img { display: block; max-width: none; }
figcaption { color: var(--muted); font-size: 0.9em; }
#detail-overlay { position: fixed; inset: 0; background: rgba(20, 25, 35, 0.55); z-index: 10; display: flex;
                  align-items: flex-start; justify-content: center; overflow-y: auto; padding: 2rem 1rem; }
#detail-overlay[hidden] { display: none; }
#detail-box { background: var(--bg); border-radius: 6px; padding: 1rem 1.4rem 1.4rem; max-width: 64rem;
              width: 100%; box-shadow: 0 6px 30px rgba(0, 0, 0, 0.3); }
#detail-close { float: right; font: inherit; cursor: pointer; }
.detail h2 { margin-top: 0.2rem; }
.detail dl { display: grid; grid-template-columns: max-content 1fr; gap: 0.2rem 1rem; }
.detail dt { color: var(--muted); }
.detail dd { margin: 0; }
.detail img { max-width: 100%; border: 1px solid var(--line); }
.detail table { margin-bottom: 0.6rem; }
code { font-size: 0.92em; }
"""

JS = r"""
(function () {
  "use strict";
  var plotData = JSON.parse(document.getElementById("plot-data").textContent);

  function fillPlots(root) {
    root.querySelectorAll("img[data-plot]").forEach(function (img) {
      var uri = plotData[img.getAttribute("data-plot")];
      if (uri && !img.getAttribute("src")) { img.setAttribute("src", uri); }
    });
  }

  function cellKey(row, index, numeric) {
    var raw = row.cells[index].getAttribute("data-value");
    if (raw === null || raw === "") { return null; }
    if (!numeric) { return raw.toLowerCase(); }
    var value = parseFloat(raw);
    return isFinite(value) ? value : null;
  }

  function sortTable(th) {
    var table = th.closest("table");
    var index = Array.prototype.indexOf.call(th.parentNode.children, th);
    var numeric = th.getAttribute("data-type") === "number";
    var dir = th.getAttribute("aria-sort") === "ascending" ? -1 : 1;
    var body = table.tBodies[0];
    var rows = Array.prototype.slice.call(body.rows);
    rows.sort(function (a, b) {
      var x = cellKey(a, index, numeric), y = cellKey(b, index, numeric);
      if (x === null || y === null) { return (x === null) - (y === null); }
      return x < y ? -dir : (x > y ? dir : 0);
    });
    rows.forEach(function (row) { body.appendChild(row); });
    table.querySelectorAll("th").forEach(function (other) { other.removeAttribute("aria-sort"); });
    th.setAttribute("aria-sort", dir === 1 ? "ascending" : "descending");
  }

  function selected(id) { return document.getElementById(id).value; }

  function applyFilters() {
    var task = selected("filter-task"), track = selected("filter-track");
    var kind = selected("filter-kind"), safety = selected("filter-safety");
    var shown = 0;
    document.querySelectorAll("section.board").forEach(function (section) {
      var match = (!task || section.getAttribute("data-task") === task) &&
                  (!track || section.getAttribute("data-track") === track);
      var visible = 0;
      section.querySelectorAll("tbody tr").forEach(function (row) {
        var ok = match && (!kind || row.getAttribute("data-kind") === kind) &&
                 (!safety || row.getAttribute("data-safety-filter") === safety);
        row.hidden = !ok;
        visible += ok ? 1 : 0;
      });
      section.hidden = visible === 0;
      shown += visible;
    });
    document.getElementById("shown-count").textContent =
      shown + " of " + document.querySelectorAll("section.board tbody tr").length + " rows shown";
  }

  function openDetail(slug) {
    var template = document.getElementById("detail-" + slug);
    var body = document.getElementById("detail-body");
    body.textContent = "";
    if (template) { body.appendChild(template.content.cloneNode(true)); fillPlots(body); }
    document.getElementById("detail-overlay").hidden = false;
    document.getElementById("detail-close").focus();
  }

  function closeDetail() { document.getElementById("detail-overlay").hidden = true; }

  document.querySelectorAll("table.ranking th").forEach(function (th) {
    th.addEventListener("click", function () { sortTable(th); });
  });
  ["filter-task", "filter-track", "filter-kind", "filter-safety"].forEach(function (id) {
    document.getElementById(id).addEventListener("change", applyFilters);
  });
  document.getElementById("show-extra").addEventListener("change", function (event) {
    document.body.classList.toggle("show-extra", event.target.checked);
  });
  document.querySelectorAll("button.entry-link").forEach(function (button) {
    button.addEventListener("click", function () { openDetail(button.getAttribute("data-slug")); });
  });
  document.getElementById("detail-close").addEventListener("click", closeDetail);
  document.getElementById("detail-overlay").addEventListener("click", function (event) {
    if (event.target.id === "detail-overlay") { closeDetail(); }
  });
  document.addEventListener("keydown", function (event) { if (event.key === "Escape") { closeDetail(); } });
  fillPlots(document);
  applyFilters();
}());
"""
