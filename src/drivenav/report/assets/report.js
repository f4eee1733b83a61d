// drivenav run report: sorting and filtering on top of plain tables (they read fine without this script).
"use strict";

function cellValue(row, index) {
  const cell = row.cells[index];
  return cell.dataset.sort !== undefined ? cell.dataset.sort : cell.textContent.trim();
}

function compareValues(a, b) {
  const x = parseFloat(a), y = parseFloat(b);
  const numbers = a !== "" && b !== "" && !isNaN(x) && !isNaN(y) && isFinite(a) && isFinite(b);
  if (numbers) return x - y;
  if (a === "" || b === "") return (a === "") - (b === "");  // empty values last
  return a.localeCompare(b);
}

function sortBy(table, index, header) {
  const ascending = header.getAttribute("aria-sort") !== "ascending";
  for (const th of table.tHead.rows[0].cells) th.removeAttribute("aria-sort");
  header.setAttribute("aria-sort", ascending ? "ascending" : "descending");
  const body = table.tBodies[0];
  const rows = Array.from(body.rows);
  rows.sort((r, s) => (ascending ? 1 : -1) * compareValues(cellValue(r, index), cellValue(s, index)));
  body.append(...rows);
}

function makeSortable(table) {
  Array.from(table.tHead.rows[0].cells).forEach((th, index) => {
    const button = document.createElement("button");
    button.type = "button";
    button.textContent = th.textContent;
    button.title = "sort by " + th.textContent;
    button.addEventListener("click", () => sortBy(table, index, th));
    th.textContent = "";
    th.append(button);
  });
}

function readState(form) {
  const state = {};
  for (const control of form.elements) {
    if (control.name && control.value !== "") state[control.name] = control.value;
  }
  return state;
}

function writeHash(state) {
  const hash = new URLSearchParams(state).toString();
  history.replaceState(null, "", hash ? "#" + hash : location.pathname + location.search);
}

function stateFromHash(form) {
  const params = new URLSearchParams(location.hash.slice(1));
  for (const control of form.elements) {
    if (control.name) control.value = params.get(control.name) || "";
  }
}

function solvedSets(rows) {
  const byRun = {};
  for (const row of rows) {
    const run = (byRun[row.dataset.method] = byRun[row.dataset.method] || {});
    run[row.dataset.episode] = row.dataset.success;
  }
  return byRun;
}

function rowMatches(row, state, byRun) {
  const data = row.dataset;
  for (const field of ["method", "success", "cause", "stop", "category", "scene", "split"]) {
    if (state[field] !== undefined && data[field] !== state[field]) return false;
  }
  const geo = parseFloat(data.geo);
  if (state["geo-min"] !== undefined && !(geo >= parseFloat(state["geo-min"]))) return false;
  if (state["geo-max"] !== undefined && !(geo <= parseFloat(state["geo-max"]))) return false;
  if (state.solved !== undefined || state.unsolved !== undefined) {
    const solved = byRun[state.solved] || {}, unsolved = byRun[state.unsolved] || {};
    const episode = data.episode;
    if (state.solved !== undefined && solved[episode] !== "1") return false;
    if (state.unsolved !== undefined && unsolved[episode] !== "0") return false;
    const runs = [state.solved, state.unsolved].filter((name) => name !== undefined);
    if (!runs.includes(data.method)) return false;
  }
  return true;
}

function applyFilters(form, table, byRun, count) {
  const state = readState(form);
  let shown = 0;
  for (const row of table.tBodies[0].rows) {
    const match = rowMatches(row, state, byRun);
    row.hidden = !match;
    shown += match;
  }
  count.value = shown + " of " + table.tBodies[0].rows.length + " rows";
  return state;
}

function makeFilterable(table) {
  const form = document.getElementById("filters");
  if (!form) return;
  const count = document.getElementById("row-count");
  const byRun = solvedSets(table.tBodies[0].rows);
  form.hidden = false;
  stateFromHash(form);
  applyFilters(form, table, byRun, count);
  const update = () => writeHash(applyFilters(form, table, byRun, count));
  form.addEventListener("input", update);
  form.addEventListener("change", update);
  form.addEventListener("submit", (event) => event.preventDefault());
  form.addEventListener("reset", () => setTimeout(update, 0));
  window.addEventListener("hashchange", () => {
    stateFromHash(form);
    applyFilters(form, table, byRun, count);
  });
}

document.addEventListener("DOMContentLoaded", () => {
  for (const table of document.querySelectorAll("table.sortable")) makeSortable(table);
  for (const table of document.querySelectorAll("table.filterable")) makeFilterable(table);
});
