// The document title: what the page shows, then the product, so tabs and history tell pages apart.
export function setTitle(what) {
  document.title = what ? `${what} – cutload` : 'cutload';
}
