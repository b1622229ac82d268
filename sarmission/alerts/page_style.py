"""The operator page's style sheet: light, high-contrast theme for daylight use.

Desktop: the map on the left, the alert list scrolling on the right. Narrower than 820 px (a
phone): the map above, the list scrolling below it, buttons at least 44 px tall. Tiers read at a
glance: confirmed alerts red, candidates amber and marked "unconfirmed" (no flash), dismissed
alerts grey, discarded candidates hidden unless asked for.
"""

PAGE_CSS = """
  :root { --red: #c62828; --amber: #b26a00; --cand: #f2a900; --green: #2e7d32; --ink: #111;
          --muted: #555; --line: #d0d0d0; --bg: #f4f4f2; --grey: #757575; }
  * { box-sizing: border-box; }
  html, body { height: 100%; }
  body { margin: 0; display: flex; flex-direction: column;
         font: 16px/1.4 system-ui, -apple-system, "Segoe UI", Roboto, sans-serif;
         color: var(--ink); background: var(--bg); }
  header { flex: none; display: flex; flex-wrap: wrap; gap: 8px 22px; align-items: center;
           padding: 10px 20px; background: #1d2733; color: #fff; }
  header h1 { margin: 0; font-size: 20px; letter-spacing: .02em; }
  .status { display: flex; align-items: center; gap: 8px; font-weight: 600; }
  .dot { width: 12px; height: 12px; border-radius: 50%; background: var(--amber); }
  body[data-live="1"] .dot { background: #4caf50; }
  .counts { font-weight: 600; }
  .counts .unacked { color: #ff8a80; }
  .counts .review { color: #ffd54f; }
  header label { font-size: 14px; }
  header input[type=text], header input:not([type]) { font: inherit; font-size: 14px;
           padding: 4px 6px; width: 10em; border: 0; border-radius: 4px; }
  header .toggle { display: flex; align-items: center; gap: 6px; }
  header .toggle input { width: 18px; height: 18px; }
  header nav { margin-left: auto; font-size: 14px; }
  header nav a { color: #cfe3ff; margin-left: 12px; }
  main { flex: 1; min-height: 0; display: grid;
         grid-template-columns: minmax(300px, 5fr) minmax(420px, 7fr); }
  .mapbox { position: relative; min-height: 0; background: #e9eef1;
            border-right: 1px solid var(--line); }
  #map { display: block; width: 100%; height: 100%; touch-action: manipulation;
         user-select: none; -webkit-user-select: none; }
  .list { min-height: 0; overflow-y: auto; padding: 16px 20px 40px; }
  .empty { color: var(--muted); text-align: center; padding: 48px 0; font-size: 18px; }
  .help { color: var(--muted); font-size: 14px; margin-top: 24px; }
  .help summary { cursor: pointer; }
  .help dt { font-weight: 600; margin-top: 8px; }
  .help dd { margin: 2px 0 0 16px; }
  .alert { display: grid; grid-template-columns: 136px 1fr auto; gap: 6px 18px;
           align-items: center; background: #fff; border: 1px solid var(--line);
           border-left: 8px solid var(--red); border-radius: 6px; padding: 12px 16px;
           margin-bottom: 12px; box-shadow: 0 1px 2px rgba(0,0,0,.06); }
  .alert.fresh { animation: flash 1.6s ease-out 2; }
  @keyframes flash { 0% { background: #ffebee; } 100% { background: #fff; } }
  .alert[data-acknowledged="1"][data-kind="alert"] { border-left-color: var(--green);
           background: #fafafa; }
  .alert[data-kind="candidate"] { border-left-color: var(--cand); background: #fffdf5; }
  .alert[data-kind="discarded"] { border-left-color: #c9b77a; background: #f7f6f1; color: #444; }
  .alert[data-kind="dismissed"] { border-left-color: var(--grey); background: #eeeeee;
           color: #555; }
  .alert[data-kind="dismissed"] .thumb { filter: grayscale(1); opacity: .6; }
  body:not(.show-discarded) .alert[data-kind="discarded"] { display: none; }
  .alert[data-settling="1"] { display: none; }
  .alert.highlight { outline: 3px solid #1565c0; outline-offset: 1px; }
  .alert > * { grid-column: 2; }
  .alert > .thumb { grid-column: 1; grid-row: 1 / span 4; }
  .alert > .side { grid-column: 3; grid-row: 1 / span 4; text-align: right; display: flex;
                   flex-direction: column; align-items: flex-end; gap: 6px; }
  .thumb { width: 128px; height: 128px; border-radius: 4px; background: #222;
           object-fit: cover; image-rendering: pixelated; }
  .nothumb { display: flex; align-items: center; justify-content: center; color: #aaa;
             font-size: 13px; }
  .title { font-size: 22px; font-weight: 700; }
  .title .score { font-weight: 600; color: var(--muted); margin-left: 6px; }
  .title .likely { margin-left: 6px; }
  .title .likely.low { color: var(--muted); font-style: italic; }
  .title .target { font-size: 15px; font-weight: 600; color: var(--muted); margin-left: 10px; }
  .badge { display: inline-block; vertical-align: middle; font-size: 13px; font-weight: 700;
           letter-spacing: .04em; text-transform: uppercase; padding: 2px 8px;
           border-radius: 4px; margin-left: 10px; }
  .badge.candidate { background: #fff3c4; color: #6b4a00; border: 1px solid var(--cand); }
  .badge.discarded { background: #ecebe4; color: #5b5640; border: 1px solid #c9b77a; }
  .badge.dismissed { background: #e0e0e0; color: #424242; border: 1px solid var(--grey); }
  .where { display: flex; flex-wrap: wrap; align-items: baseline; gap: 4px 14px; }
  .coords { font: 600 20px/1.2 ui-monospace, "DejaVu Sans Mono", Menlo, Consolas, monospace;
            color: var(--ink); background: #eef3fb; border: 1px solid #b9cbe6;
            border-radius: 4px; padding: 3px 8px; cursor: copy; }
  .coords:hover { background: #dde8f8; }
  .coords.copied { background: #dff3e0; border-color: #8bc34a; }
  .err { font-weight: 600; }
  .asof, .drift { color: var(--muted); margin-left: 6px; }
  .nopos { color: var(--amber); font-weight: 700; }
  .meta, .state { color: var(--muted); font-size: 14px; }
  .state { font-weight: 600; }
  .chip { display: inline-block; font-size: 12px; font-weight: 600; padding: 1px 7px;
          border-radius: 10px; background: #e8eaf6; color: #283593; margin-right: 6px; }
  .chip.refused { background: #fde7e7; color: #8b1a1a; }
  .side button { font: 700 16px system-ui, sans-serif; border-radius: 6px; padding: 10px 18px;
                 min-height: 44px; min-width: 120px; cursor: pointer; }
  .side button:hover { filter: brightness(1.1); }
  .side button:disabled { opacity: .6; cursor: wait; }
  .ack { color: #fff; background: var(--red); border: 0; min-width: 150px; }
  .confirm { color: #fff; background: var(--green); border: 0; }
  .dismiss { color: #333; background: #fff; border: 2px solid #9e9e9e; }
  .acked { color: var(--green); font-weight: 700; }
  .ackerr { color: var(--red); font-size: 13px; }
  @media (max-width: 820px) {
    header { padding: 6px 10px; gap: 4px 14px; }
    header h1 { font-size: 17px; }
    header nav { margin-left: 0; }
    header nav a { margin: 0 10px 0 0; }
    main { grid-template-columns: 1fr; grid-template-rows: minmax(220px, 40vh) 1fr; }
    .mapbox { border-right: 0; border-bottom: 1px solid var(--line); }
    .list { padding: 10px 8px 30px; }
    .alert { grid-template-columns: 84px 1fr; gap: 4px 12px; padding: 10px; }
    .alert > .thumb { grid-row: 1 / span 3; }
    .alert > .side { grid-column: 1 / -1; grid-row: auto; text-align: left;
                     flex-direction: row; flex-wrap: wrap; align-items: center; gap: 8px; }
    .side button { flex: 1 1 40%; }
    .thumb { width: 84px; height: 84px; }
    .title { font-size: 18px; }
    .coords { font-size: 15px; }
  }
"""
