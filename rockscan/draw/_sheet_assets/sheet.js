(function () {
  const sheet = document.getElementById('sheet');
  const cards = Array.from(sheet.querySelectorAll('figure.card'));
  const numeric = new Set(['rank', 'interest', 'mscore', 'angle', 'novelty', 'segmentation']);
  const descending = new Set(['interest', 'mscore', 'novelty', 'segmentation']);
  const state = { key: 'rank', ascending: true };
  const $ = (id) => document.getElementById(id);

  // The shape menu lists the shapes on the page.
  const shapes = Array.from(new Set(cards.map((c) => c.dataset.match).filter((s) => s))).sort();
  for (const name of shapes) {
    const option = document.createElement('option');
    option.value = name;
    option.textContent = name;
    $('shape').appendChild(option);
  }

  function value(card, key) {
    const raw = card.dataset[key];
    if (!numeric.has(key)) return raw.toLowerCase();
    return raw === '' ? null : parseFloat(raw);
  }
  function tie(a, b) {
    const pa = value(a, 'path'), pb = value(b, 'path');
    if (pa !== pb) return pa < pb ? -1 : 1;
    return parseInt(a.dataset.index || '0', 10) - parseInt(b.dataset.index || '0', 10);
  }
  function compare(a, b) {
    const va = value(a, state.key), vb = value(b, state.key);
    // Rows without the value (errors) stay last whichever way the sort goes.
    if (va === null || vb === null) {
      if (va === vb) return tie(a, b);
      return va === null ? 1 : -1;
    }
    let order = va < vb ? -1 : va > vb ? 1 : 0;
    if (!state.ascending) order = -order;
    return order === 0 ? tie(a, b) : order;
  }
  function visible(card) {
    const text = $('filter').value.trim().toLowerCase();
    const shape = $('shape').value;
    const least = parseFloat($('min-interest').value);
    const d = card.dataset;
    if (text && !(d.path.toLowerCase().includes(text) || d.match.toLowerCase().includes(text))) return false;
    if (shape && d.match !== shape) return false;
    if (!isNaN(least) && !(d.interest !== '' && parseFloat(d.interest) >= least)) return false;
    if ($('only-interesting').checked && d.interesting !== '1') return false;
    if ($('only-novel').checked && d.novel !== '1') return false;
    if (!$('show-errors').checked && d.error === '1') return false;
    return true;
  }
  function apply() {
    cards.sort(compare);
    let shown = 0;
    for (const card of cards) {
      const show = visible(card);
      card.hidden = !show;
      shown += show;
      sheet.appendChild(card);
    }
    $('count').textContent = shown + ' of ' + cards.length + ' shown';
    for (const button of document.querySelectorAll('button.sort')) {
      const active = button.dataset.key === state.key;
      button.classList.toggle('active', active);
      button.setAttribute('aria-pressed', active ? 'true' : 'false');
      button.textContent = button.dataset.label + (active ? (state.ascending ? ' \u2191' : ' \u2193') : '');
    }
  }
  for (const button of document.querySelectorAll('button.sort')) {
    button.dataset.label = button.textContent;
    button.addEventListener('click', () => {
      const key = button.dataset.key;
      if (state.key === key) state.ascending = !state.ascending;
      else { state.key = key; state.ascending = !descending.has(key); }
      apply();
    });
  }
  for (const id of ['filter', 'shape', 'min-interest', 'only-interesting', 'only-novel', 'show-errors']) {
    $(id).addEventListener('input', apply);
    $(id).addEventListener('change', apply);
  }
  apply();
})();
