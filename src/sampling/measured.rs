//! Importance sampling of the measured materials, which have no closed form to invert: both sample a
//! [`Proxy`] (fitted once per material with [`fit_proxy`](MerlTable::fit_proxy), or [`Proxy::COSINE`])
//! and evaluate the material itself for the weight.

use super::{fit_proxy, BsdfSample, Proxy};
use crate::measured::{MerlTable, NbrdfNetwork};
use crate::Vec3;

impl MerlTable {
    /// The sampling proxy of this table ([`fit_proxy`] on its nearest-bin lookup).
    pub fn fit_proxy(&self) -> Proxy {
        fit_proxy(|wi, wo| self.eval(wi, wo))
    }

    /// Samples `proxy` for the view `wo` and weighs by the table's value (nearest lookup, like
    /// [`MerlTable::eval`]). (`sample` already names the raw-bin accessor of the table.)
    #[inline]
    pub fn sample_with(&self, proxy: &Proxy, u: [f32; 3], wo: Vec3) -> Option<BsdfSample> {
        proxy.sample(u, wo, |wi, wo| self.eval(wi, wo))
    }

    /// Density of [`MerlTable::sample_with`]: the proxy's.
    #[inline]
    pub fn pdf_with(&self, proxy: &Proxy, wo: Vec3, wi: Vec3) -> f32 {
        proxy.pdf(wo, wi)
    }
}

impl NbrdfNetwork {
    /// The sampling proxy of this network ([`fit_proxy`] on its evaluation).
    ///
    /// ```no_run
    /// let net = nbrdf::measured::NbrdfNetwork::load("../shared/data/nbrdf-merl/chrome.json").unwrap();
    /// let proxy = net.fit_proxy();
    /// let s = net.sample_with(&proxy, [0.2, 0.7, 0.5], nbrdf::Vec3::new(0.3, 0.0, 0.9).normalize());
    /// ```
    pub fn fit_proxy(&self) -> Proxy {
        fit_proxy(|wi, wo| self.eval(wi, wo))
    }

    /// Samples `proxy` for the view `wo` and weighs by the network's value.
    #[inline]
    pub fn sample_with(&self, proxy: &Proxy, u: [f32; 3], wo: Vec3) -> Option<BsdfSample> {
        proxy.sample(u, wo, |wi, wo| self.eval(wi, wo))
    }

    /// Density of [`NbrdfNetwork::sample_with`]: the proxy's.
    #[inline]
    pub fn pdf_with(&self, proxy: &Proxy, wo: Vec3, wi: Vec3) -> f32 {
        proxy.pdf(wo, wi)
    }
}
