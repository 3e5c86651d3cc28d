//! The `swap` request-response service: `lavatube swap-learner` asks the launcher to replace
//! a learner.

use super::{Bus, IpcError, Svc, ipc_err};
use crate::wire::{SwapReply, SwapRequest};

/// Service ports of the `swap` request-response service (`lavatube swap-learner` → launcher).
pub type SwapServer = iceoryx2::port::server::Server<Svc, SwapRequest, (), SwapReply, ()>;
pub type SwapClient = iceoryx2::port::client::Client<Svc, SwapRequest, (), SwapReply, ()>;

impl Bus {
    fn swap_service(
        &self,
    ) -> Result<
        iceoryx2::service::port_factory::request_response::PortFactory<
            Svc,
            SwapRequest,
            (),
            SwapReply,
            (),
        >,
        IpcError,
    > {
        let name = self.service_name("swap", None)?;
        self.node()
            .service_builder(&name)
            .request_response::<SwapRequest, SwapReply>()
            .open_or_create()
            .map_err(|e| ipc_err(format!("open service `{name}`"))(&e))
    }

    /// The launcher's side of `swap`.
    pub fn swap_server(&self) -> Result<SwapServer, IpcError> {
        self.swap_service()?
            .server_builder()
            .create()
            .map_err(|e| ipc_err("swap server")(&e))
    }

    /// `lavatube swap-learner`'s side of `swap`.
    pub fn swap_client(&self) -> Result<SwapClient, IpcError> {
        self.swap_service()?
            .client_builder()
            .create()
            .map_err(|e| ipc_err("swap client")(&e))
    }
}
